"""One IMU of the daemon: its calibration, pipeline, Zenoh sink, health and queryable.

:class:`ImuChannel` holds everything the daemon keeps per IMU; the process-wide
parts (the bus, the Zenoh session, the loop, signals, sd_notify) stay in
:class:`gyrotherm.daemon.Daemon`, which has one channel per configured IMU and
hands each frame to the channel owning its id (:mod:`gyrotherm.daemon._router`).

A calibration that cannot be used at start stops the daemon (exit 2) when the
configuration has one IMU, as always. With several IMUs (``tolerant``) it must
not stop the others: the channel logs the error, runs that IMU without a
calibration (``NO_CALIBRATION``: raw rates, flagged) and takes a good file on the
next reload (SIGHUP).
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from typing import TYPE_CHECKING, Any

import zenoh

from gyrotherm._zenoh import keys, zenoh_error_text
from gyrotherm.codecs import FrameDecoder
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
)
from gyrotherm.compensation import Calibration
from gyrotherm.daemon._calload import load_daemon_calibration
from gyrotherm.daemon._config import DaemonConfig
from gyrotherm.daemon._effects_store import EffectsKeeper
from gyrotherm.daemon._pipeline import Pipeline
from gyrotherm.daemon._sink import _ZenohSink

if TYPE_CHECKING:  # loaded only when [learn] is configured
    from gyrotherm.daemon._learner import Learner

log = logging.getLogger("gyrotherm.daemon")


class ImuChannel:
    """The per-IMU state of the daemon (module docstring)."""

    def __init__(self, config: DaemonConfig, *, tolerant: bool = False) -> None:
        self.config = config
        self.sensor = config.sensor
        self.keys = keys(config.vehicle, config.sensor)
        self.calibration: Calibration | None = None
        self.calibration_id = ""
        self.calibration_error: str | None = None
        """Why the configured calibration is not in use (tolerant start), else None."""
        self.reloads = 0
        self.reload_failures = 0
        self.effects_keeper = EffectsKeeper(config.state_dir, config.vehicle, config.sensor)
        if config.calibration is not None:
            try:
                self.calibration, self.calibration_id = self.read_calibration()
            except Exception as exc:
                if not tolerant:
                    raise
                self.calibration_error = str(exc)
                log.error("%s: calibration refused, this IMU runs uncorrected "
                          "(NO_CALIBRATION) until a reload takes a good file: %s",
                          self.sensor, exc)
        self.learner: Learner | None = None
        if config.learn is not None:
            from gyrotherm.daemon._learner import Learner  # only with [learn]: footprint

            assert config.state_dir is not None  # parse_config requires it
            self.learner = Learner(
                config.learn, vehicle=config.vehicle, sensor=config.sensor,
                state_dir=config.state_dir, power_on_gap_s=config.power_on_gap_s,
                estimator=self.calibration.estimator if self.calibration else config.estimator,
                device_id=config.device_id, device_mismatch=config.device_mismatch)
            self.calibration, self.calibration_id = self.learner.start(
                self.calibration, self.calibration_id)
        self.pipeline: Pipeline | None = None
        self.sink: _ZenohSink | None = None
        self.health_seq = 0
        self.last_health = -math.inf
        self.last_frame = time.monotonic()
        self._seen = 0
        # What the queryable answers, replaced whole by the loop thread (never mutated):
        # zenoh calls on_query on its own thread.
        self.snapshot = CalibrationInfo(self.calibration_id, self._calibration_dict(), None)

    def read_calibration(self) -> tuple[Calibration, str]:
        cfg = self.config
        assert cfg.calibration is not None
        return load_daemon_calibration(cfg.calibration, device_id=cfg.device_id,
                                       device_mismatch=cfg.device_mismatch)

    def _calibration_dict(self) -> dict[str, Any] | None:
        return self.calibration.to_dict() if self.calibration else None

    def start(self, session: zenoh.Session, stack: contextlib.ExitStack) -> Pipeline:
        """Publishers, pipeline, restored effects and queryable; released by ``stack``."""
        cfg = self.config
        decoder = FrameDecoder(cfg.can.dbc, cfg.can.signals,
                               on_counter_jump=cfg.can.on_counter_jump)  # type: ignore[arg-type]
        sink = _ZenohSink(session, cfg)
        stack.callback(sink.undeclare)
        self.sink = sink
        pipeline = Pipeline(decoder, sink, calibration=self.calibration,
                            estimator=cfg.estimator,
                            check_counters=cfg.can.on_counter_jump == "deliver",
                            power_on_gap_s=cfg.power_on_gap_s, zero=cfg.zero)
        self.pipeline = pipeline
        self.effects_keeper.restore(pipeline.compensation, self.calibration_id)
        stack.callback(self.save_effects, pipeline, force=True)
        if self.learner is not None:
            pipeline.attach_learner(self.learner)
            self.learner.on_adopt = self._adopt
            stack.callback(self.learner.shutdown)
        queryable = session.declare_queryable(self.keys.calibration, self.on_query)
        stack.callback(queryable.undeclare)
        return pipeline

    def _adopt(self, calibration: Calibration, calibration_id: str) -> None:
        """The learner adopted ``calibration`` (called on the frame thread, between two
        frames): the pipeline, the status line, health and the queryable take it."""
        assert self.pipeline is not None
        self.pipeline.set_calibration(calibration)
        self.calibration, self.calibration_id = calibration, calibration_id
        self.calibration_error = None
        self.snapshot = CalibrationInfo(calibration_id, self._calibration_dict(),
                                        self.snapshot.health)

    def tend_learning(self, now_s: float) -> None:
        """Housekeeping: a finished learning decision is taken, the state saved now and then."""
        if self.learner is not None:
            self.learner.tick(now_s)

    def frame_keys(self) -> tuple[int, int]:
        """The lookup keys (id, + EXTENDED_KEY if extended) of this IMU's two messages."""
        assert self.pipeline is not None
        layout = self.pipeline.decoder.layout
        return layout.rate.key, layout.temperature.key

    def on_query(self, query: zenoh.Query) -> None:
        # runs on a zenoh thread: read the one immutable snapshot, nothing else
        query.reply(self.keys.calibration, encode_calibration_info(self.snapshot))

    def save_effects(self, pipeline: Pipeline, *, force: bool = False) -> None:
        self.effects_keeper.save(pipeline.compensation, self.calibration_id,
                                 time.monotonic(), force=force)

    def note_frames(self, now: float) -> None:
        """At housekeeping: frames arrived since the last call make ``last_frame`` now."""
        assert self.pipeline is not None
        n = self.pipeline.frames_received
        if n != self._seen:
            self._seen, self.last_frame = n, now

    def publish_health(self, now: float, started: float, *, silent: bool) -> None:
        pipeline, sink = self.pipeline, self.sink
        assert pipeline is not None and sink is not None
        self.last_health = now
        pipeline.tick()
        extra = StatusFlags.TEMPERATURE_STALE if silent else StatusFlags.NONE
        health: HealthMessage = pipeline.health(
            seq=self.health_seq, receive_time_s=time.time(), uptime_s=now - started,
            calibration_id=self.calibration_id, extra_flags=extra)
        # the queryable's snapshot first: a subscriber that saw this health message and
        # then asks must never get an older one
        self.snapshot = CalibrationInfo(self.calibration_id, self._calibration_dict(), health)
        try:
            sink.health.put(encode_health(health))
            self.health_seq += 1
        except zenoh.ZError as exc:
            log.warning("%s: health publish failed: %s", self.sensor, zenoh_error_text(exc))

    def reload(self, pipeline: Pipeline, *, prefix: str = "") -> None:
        """SIGHUP: read the calibration file again; a bad one keeps the current one."""
        path = self.config.calibration
        if path is None:
            log.warning("%sSIGHUP: no calibration file configured; nothing to reload", prefix)
            return
        learner = self.learner
        try:
            cal, cid = self.read_calibration()
            if learner is not None and learner.adopted:
                log.info("%scalibration file %s (%s) is valid, but the learnt calibration %s "
                         "stays in use (remove %s and restart to go back to the file)",
                         prefix, path, cid, self.calibration_id, learner.learnt_path)
                return
            pipeline.set_calibration(cal)
            if learner is not None:
                learner.set_current(cal, cid)
        except Exception as exc:  # a bad file must never stop the daemon
            self.reload_failures += 1
            log.error("%scalibration reload failed, keeping %s: %s", prefix,
                      self.calibration_id or "none", exc)
        else:
            self.calibration, self.calibration_id = cal, cid
            self.calibration_error = None
            self.reloads += 1
            log.info("%scalibration reloaded: %s (%s)", prefix, path, cid)
            self.snapshot = CalibrationInfo(cid, self._calibration_dict(), self.snapshot.health)
