"""The daemon: a python-can bus in, Zenoh out, under systemd.

Loop (one thread): ``recv(timeout)`` a frame → :class:`Pipeline` → Zenoh
publishers. Housekeeping runs from the same loop at least every
``recv_timeout_s``: the health message every ``health_period_s``, predict-only
estimation when temperature frames stop, the systemd watchdog (so a stuck
pipeline stops petting it and gets restarted), STATUS= lines and calibration
reloads.

Start: the Zenoh session opens, then the bus is waited for (attempts with
backoff until ``[can] start_timeout_s``, :mod:`gyrotherm.daemon._buskeeper`);
READY=1 only once both are up. A lost or silent bus is reopened in the
background while the loop keeps running (watchdog, health).

Signals: SIGTERM and SIGINT stop the daemon in every state — starting, waiting
for the bus, mid-handshake, reopening, blocked on a publish (at most
``[zenoh] publish_block_max_s``): every open runs on a worker thread and every
wait is an event wait of at most ``recv_timeout_s``
(:mod:`gyrotherm.daemon._attempt`); publishers are undeclared, session and bus
closed. The handlers only set a flag (a handler must take no lock). SIGHUP
reloads the calibration atomically — a bad file keeps the old calibration,
logs why and counts ``reload_failures``; the same calibration keeps its effects'
state, another one takes it over when its effects are of the same kinds
(:mod:`gyrotherm.daemon._compensation`). Version-1 and version-2 (effects)
calibrations both run; with ``state_dir`` the effects' state survives a restart
(:mod:`gyrotherm.daemon._effects_store`).

The Zenoh side (publishers, matching status, transport events) is
:class:`~gyrotherm.daemon._sink._ZenohSink`; its module docstring states how
puts nobody receives are counted.
"""

from __future__ import annotations

import contextlib
import logging
import math
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import zenoh

from gyrotherm._memory import TRIM_PERIOD_S, release_free_heap
from gyrotherm._zenoh import keys, session_config, zenoh_error_text
from gyrotherm.bus import FrameSource
from gyrotherm.codecs import FrameDecoder
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
)
from gyrotherm.compensation import Calibration
from gyrotherm.daemon._attempt import close_session, open_session
from gyrotherm.daemon._buskeeper import BusKeeper
from gyrotherm.daemon._calload import load_daemon_calibration
from gyrotherm.daemon._config import DaemonConfig
from gyrotherm.daemon._effects_store import EffectsKeeper
from gyrotherm.daemon._pipeline import Counters, Pipeline
from gyrotherm.daemon._sdnotify import Notifier
from gyrotherm.daemon._sink import _ZenohSink, bound_publishing

log = logging.getLogger("gyrotherm.daemon")


@dataclass(frozen=True)
class RunSummary:
    """What a daemon run did (returned by :meth:`Daemon.run`)."""

    frames_received: int
    frames_published: int
    drops: dict[str, int]
    reloads: int
    reload_failures: int
    uptime_s: float


class Daemon:
    """The gyrotherm service for one sensor."""

    def __init__(self, config: DaemonConfig, *, notifier: Notifier | None = None) -> None:
        self.config = config
        self._notifier = notifier or Notifier.from_environment()
        self._stop = threading.Event()
        self._reload = threading.Event()
        self.ready = threading.Event()
        """Set once the bus and the Zenoh session are up (for tests and embedding)."""
        self.reloads = 0
        self.reload_failures = 0
        self._calibration: Calibration | None = None
        self._calibration_id = ""
        self._pipeline: Pipeline | None = None
        self._sink: _ZenohSink | None = None
        self._started = time.monotonic()
        self._health_seq = 0
        self._last_health = -math.inf
        self._last_trim = time.monotonic()
        self._last_frame = time.monotonic()
        self._bus: FrameSource | None = None
        self._signalled: int | None = None  # set by the signal handlers (no locks there)
        self._hup = False
        self._keeper = BusKeeper(config.can, self._stopping, self._notifier.status)
        self.effects_keeper = EffectsKeeper(config.state_dir, config.vehicle, config.sensor)
        if config.calibration is not None:
            self._calibration, self._calibration_id = self._read_calibration(config.calibration)
        # What the queryable answers, replaced whole by the loop thread (never mutated):
        # zenoh calls _on_query on its own thread.
        self._snapshot = CalibrationInfo(self._calibration_id, self._calibration_dict(), None)

    # --- control (thread-safe) -----------------------------------------------------

    def stop(self) -> None:
        self._stop.set()

    def _stopping(self) -> bool:
        return self._signalled is not None or self._stop.is_set()

    @property
    def bus_reopens(self) -> int:
        """How often the configured bus was shut down to be reopened."""
        return self._keeper.reopens

    def request_reload(self) -> None:
        self._reload.set()

    def install_signal_handlers(self) -> None:
        """SIGTERM/SIGINT stop, SIGHUP reloads (main thread only)."""

        def on_stop(signum: int, frame: FrameType | None) -> None:
            # no logging, no Event.set: the interrupted main thread may hold their locks
            self._signalled = signum

        def on_hup(signum: int, frame: FrameType | None) -> None:
            self._hup = True  # a plain flag, as for on_stop

        signal.signal(signal.SIGTERM, on_stop)
        signal.signal(signal.SIGINT, on_stop)
        signal.signal(signal.SIGHUP, on_hup)

    # --- the loop --------------------------------------------------------------------

    def _log_stop_reason(self) -> None:
        if self._signalled is not None:
            log.info("signal %s: stopping", signal.Signals(self._signalled).name)

    def run(self, *, source: FrameSource | None = None) -> RunSummary:
        """Run until :meth:`stop` or a signal; ``source`` overrides the configured bus."""
        cfg = self.config
        decoder = FrameDecoder(cfg.can.dbc, cfg.can.signals,
                               on_counter_jump=cfg.can.on_counter_jump)  # type: ignore[arg-type]
        z = cfg.zenoh
        zconf = (session_config(config_file=z.config_file, protect=keys(cfg.vehicle, cfg.sensor))
                 if z.config_file else
                 session_config(mode=z.mode, listen=z.listen, connect=z.connect,  # type: ignore[arg-type]
                                protect=keys(cfg.vehicle, cfg.sensor)))
        bound_publishing(zconf, z.publish_block_max_s)
        pipeline: Pipeline | None = None
        with contextlib.ExitStack() as stack:
            # every resource is released in reverse order, whatever fails later
            log.info("starting: zenoh session, then the bus %s (for at most %g s)",
                     self._keeper.where, cfg.can.start_timeout_s)
            session = open_session(zconf, self._stopping)
            if session is None:
                return self._summary(None)
            stack.callback(close_session, session)
            sink = _ZenohSink(session, cfg)
            stack.callback(sink.undeclare)
            self._sink = sink
            pipeline = Pipeline(decoder, sink, calibration=self._calibration,
                                estimator=cfg.estimator,
                                check_counters=cfg.can.on_counter_jump == "deliver",
                                power_on_gap_s=cfg.power_on_gap_s, zero=cfg.zero)
            self._pipeline = pipeline
            self.effects_keeper.restore(pipeline.compensation, self._calibration_id)
            stack.callback(self._save_effects, pipeline, force=True)
            k = keys(cfg.vehicle, cfg.sensor)
            self._reply_key = k.calibration
            queryable = session.declare_queryable(k.calibration, self._on_query)
            stack.callback(queryable.undeclare)
            stack.callback(lambda: self._notifier.stopping(status="stopping"))
            stack.callback(self._keeper.close)
            if source is not None:
                stack.callback(source.shutdown)
            bus = source or self._keeper.open_at_start()
            if bus is None:  # stopped while waiting for the bus
                return self._summary(pipeline)
            self._bus = bus
            self._started = self._last_frame = time.monotonic()
            log.info("up: %s %s → %s", cfg.can.interface, cfg.can.channel, k.rate)
            release_free_heap()  # start-up's temporaries (gyrotherm._memory)
            self._last_trim = time.monotonic()
            self.ready.set()
            self._notifier.ready(status=self._status_line())
            self._loop(pipeline, sink, reopen=source is None)
        return self._summary(pipeline)

    def _summary(self, pipeline: Pipeline | None) -> RunSummary:
        self._log_stop_reason()
        c = pipeline.counters() if pipeline else Counters(0, 0, 0, 0, {}, 0)
        log.info("stopped: %d frames in, %d published, drops %s", c.frames_received,
                 c.frames_published, c.drops)
        return RunSummary(c.frames_received, c.frames_published, c.drops, self.reloads,
                          self.reload_failures, time.monotonic() - self._started)

    def _loop(self, pipeline: Pipeline, sink: _ZenohSink, *, reopen: bool) -> None:
        process = pipeline.process
        now_wall = time.time
        mono = time.monotonic
        cpu = time.thread_time
        timeout = self.config.can.recv_timeout_s
        period = self.config.health_period_s
        next_tick = mono()
        stop = self._stop
        stopping = self._stopping
        keeper = self._keeper
        quiet = suspect = False
        bus: FrameSource | None = self._bus
        while not stopping():
            try:
                if bus is None:  # down, being reopened: wait, do not spin
                    stop.wait(timeout)
                elif not quiet:
                    msg = bus.recv(timeout)
                    quiet = msg is None
                    if msg is not None:
                        recv = bus.recv
                        process(msg, now_wall())
                        # drain what is already queued before housekeeping
                        for _ in range(256):
                            msg = recv(0.0)
                            if msg is None:
                                break
                            process(msg, now_wall())
                        self._last_frame = mono()
                else:  # quiet: a recv must wait, not return at once or burn CPU (dead peer)
                    cpu0, wall0 = cpu(), mono()
                    msg = bus.recv(timeout)
                    if msg is None:
                        wall = mono() - wall0
                        if wall < 0.5 * timeout:
                            suspect = True
                            stop.wait(timeout - wall)
                        elif cpu() - cpu0 > 0.5 * wall:
                            suspect = True
                    else:
                        quiet = False
                        process(msg, now_wall())
                        self._last_frame = mono()
            except Exception as exc:  # the bus failed at run time (CAN error, OSError …)
                if not reopen:
                    raise
                keeper.failure, suspect = exc, True
                stop.wait(timeout)
            if mono() >= next_tick:
                next_tick = mono() + min(period, 0.25)
                self._housekeeping(pipeline, sink)
                if reopen:
                    keeper.tend(self._last_frame, suspect=suspect)
                    suspect = False
                    if keeper.bus is not bus:
                        bus = self._bus = keeper.bus
                        quiet = False

    def _housekeeping(self, pipeline: Pipeline, sink: _ZenohSink) -> None:
        self._notifier.watchdog()
        if self._reload.is_set() or self._hup:
            self._reload.clear()
            self._hup = False
            self._do_reload(pipeline)
        now = time.monotonic()
        self._save_effects(pipeline)
        if now - self._last_trim >= TRIM_PERIOD_S:
            self._last_trim = now
            release_free_heap()
        if now - self._last_health >= self.config.health_period_s:
            self._last_health = now
            pipeline.tick()
            silent = now - self._last_frame > pipeline.stale_after_s or self._bus is None
            health = self._health(pipeline, silent=silent)
            # the queryable's snapshot first: a subscriber that saw this health message and
            # then asks must never get an older one
            self._snapshot = CalibrationInfo(self._calibration_id, self._calibration_dict(),
                                             health)
            try:
                sink.health.put(encode_health(health))
                self._health_seq += 1
            except zenoh.ZError as exc:
                log.warning("health publish failed: %s", zenoh_error_text(exc))
            self._notifier.status(self._status_line())

    def _do_reload(self, pipeline: Pipeline) -> None:
        path = self.config.calibration
        self._notifier.reloading(status="reloading calibration")
        if path is None:
            log.warning("SIGHUP: no calibration file configured; nothing to reload")
        else:
            try:
                cal, cid = self._read_calibration(path)
                pipeline.set_calibration(cal)
            except Exception as exc:  # a bad file must never stop the daemon
                self.reload_failures += 1
                log.error("calibration reload failed, keeping %s: %s",
                          self._calibration_id or "none", exc)
            else:
                self._calibration, self._calibration_id = cal, cid
                self.reloads += 1
                log.info("calibration reloaded: %s (%s)", path, cid)
                self._snapshot = CalibrationInfo(cid, self._calibration_dict(),
                                                 self._snapshot.health)
        self._notifier.ready(status=self._status_line())

    def _read_calibration(self, path: Path) -> tuple[Calibration, str]:
        cfg = self.config
        return load_daemon_calibration(path, device_id=cfg.device_id,
                                       device_mismatch=cfg.device_mismatch)

    def _save_effects(self, pipeline: Pipeline, *, force: bool = False) -> None:
        self.effects_keeper.save(pipeline.compensation, self._calibration_id,
                                 time.monotonic(), force=force)

    def _calibration_dict(self) -> dict[str, Any] | None:
        return self._calibration.to_dict() if self._calibration else None

    def _health(self, pipeline: Pipeline, *, silent: bool) -> HealthMessage:
        extra = StatusFlags.TEMPERATURE_STALE if silent else StatusFlags.NONE
        return pipeline.health(seq=self._health_seq, receive_time_s=time.time(),
                               uptime_s=time.monotonic() - self._started,
                               calibration_id=self._calibration_id, extra_flags=extra)

    def _on_query(self, query: zenoh.Query) -> None:
        # runs on a zenoh thread: read the one immutable snapshot, nothing else
        query.reply(self._reply_key, encode_calibration_info(self._snapshot))

    def _status_line(self) -> str:
        p = self._pipeline
        if p is None:
            return "starting"
        c = p.counters()
        dropped = sum(c.drops.values())
        zen = ""
        if self._sink is not None:
            subscribed = "yes" if self._sink.rate_matched else "none"
            zen = f"; zenoh {self._sink.transports()} transports, rate subscribers {subscribed}"
            if self._sink.congestion_episodes:
                zen += f", congestion episodes {self._sink.congestion_episodes}"
        down = self._keeper.status()
        return (f"{c.frames_received} frames, {c.frames_published} published, "
                f"{dropped} dropped; calibration {self._calibration_id or 'none'}; "
                f"flags {p.flags!r}{zen}{'; ' + down if down else ''}")
