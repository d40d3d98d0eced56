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
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import FrameType
from typing import TYPE_CHECKING, Any

import zenoh

from gyrotherm._memory import TRIM_PERIOD_S, release_free_heap
from gyrotherm._zenoh import KEY_PREFIX, KeyExprs, session_config, zenoh_error_text
from gyrotherm.bus import FrameSource, TransportItem
from gyrotherm.codecs._canmap import EXTENDED_KEY
from gyrotherm.compensation import Calibration
from gyrotherm.daemon._attempt import close_session, open_session
from gyrotherm.daemon._buskeeper import BusKeeper
from gyrotherm.daemon._config import DaemonConfig
from gyrotherm.daemon._effects_store import EffectsKeeper
from gyrotherm.daemon._imu import ImuChannel
from gyrotherm.daemon._pipeline import Counters, Pipeline
from gyrotherm.daemon._sdnotify import Notifier
from gyrotherm.daemon._sink import bound_publishing
from gyrotherm.daemon._vehicle import VehicleConfig

if TYPE_CHECKING:  # loaded only for several IMUs with a consistency check
    from gyrotherm.daemon._consistency import Consistency

log = logging.getLogger("gyrotherm.daemon")

#: Bus-level drop reason (several IMUs): a frame whose id belongs to no configured IMU.
UNKNOWN_ID = "unknown_id"


@dataclass(frozen=True)
class RunSummary:
    """What a daemon run did (returned by :meth:`Daemon.run`). With several IMUs the
    totals add every IMU's and the bus-level frames (``bus_drops``: frames of no IMU,
    transport items); ``per_imu`` has each IMU's own accounting."""

    frames_received: int
    frames_published: int
    drops: dict[str, int]
    reloads: int
    reload_failures: int
    uptime_s: float
    per_imu: Mapping[str, Counters] = field(default_factory=dict)
    bus_drops: Mapping[str, int] = field(default_factory=dict)


class Daemon:
    """The gyrotherm service: one bus, one Zenoh session, one channel per IMU."""

    def __init__(self, config: DaemonConfig | VehicleConfig, *,
                 notifier: Notifier | None = None) -> None:
        vehicle = config if isinstance(config, VehicleConfig) else VehicleConfig((config,))
        self.vehicle = vehicle
        self.config = vehicle.imus[0]
        """The first IMU's configuration (bus and Zenoh settings are the same for all)."""
        self._notifier = notifier or Notifier.from_environment()
        self._stop = threading.Event()
        self._reload = threading.Event()
        self.ready = threading.Event()
        """Set once the bus and the Zenoh session are up (for tests and embedding)."""
        self._multi = vehicle.multi
        self.channels = [ImuChannel(c, tolerant=self._multi) for c in vehicle.imus]
        self.consistency: Consistency | None = None
        if vehicle.consistency is not None and len(self.channels) > 1:
            from gyrotherm.daemon._consistency import Consistency  # several IMUs only

            self.consistency = Consistency(vehicle.sensors, vehicle.consistency)
        self._consistency_pubs: list[Any] = []
        self._bus_received = 0
        self._bus_drops: Counter[str] = Counter()
        self._started = time.monotonic()
        self._last_trim = time.monotonic()
        self._last_frame = time.monotonic()
        self._bus: FrameSource | None = None
        self._signalled: int | None = None  # set by the signal handlers (no locks there)
        self._hup = False
        self._keeper = BusKeeper(self.config.can, self._stopping, self._notifier.status)

    # --- one-IMU views (the first channel) ---------------------------------------------

    @property
    def _calibration(self) -> Calibration | None:
        return self.channels[0].calibration

    @property
    def _calibration_id(self) -> str:
        return self.channels[0].calibration_id

    @property
    def effects_keeper(self) -> EffectsKeeper:
        return self.channels[0].effects_keeper

    @property
    def reloads(self) -> int:
        return sum(ch.reloads for ch in self.channels)

    @property
    def reload_failures(self) -> int:
        return sum(ch.reload_failures for ch in self.channels)

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

    def _consistency_prefix(self) -> str:
        return f"{KEY_PREFIX}/{self.config.vehicle}/consistency"

    def _session_config(self) -> zenoh.Config:
        z = self.config.zenoh
        protect: list[KeyExprs | str] = [ch.keys for ch in self.channels]
        if self.consistency is not None:
            protect.append(self._consistency_prefix())
        guard = protect[0] if len(protect) == 1 else protect
        zconf = (session_config(config_file=z.config_file, protect=guard) if z.config_file else
                 session_config(mode=z.mode, listen=z.listen, connect=z.connect,  # type: ignore[arg-type]
                                protect=guard))
        bound_publishing(zconf, z.publish_block_max_s)
        return zconf

    def run(self, *, source: FrameSource | None = None) -> RunSummary:
        """Run until :meth:`stop` or a signal; ``source`` overrides the configured bus."""
        cfg = self.config
        zconf = self._session_config()
        with contextlib.ExitStack() as stack:
            # every resource is released in reverse order, whatever fails later
            log.info("starting: zenoh session, then the bus %s (for at most %g s)",
                     self._keeper.where, cfg.can.start_timeout_s)
            session = open_session(zconf, self._stopping)
            if session is None:
                return self._summary()
            stack.callback(close_session, session)
            for ch in self.channels:
                ch.start(session, stack)
            process = self._process_for_bus()
            self._declare_consistency(session, stack)
            stack.callback(lambda: self._notifier.stopping(status="stopping"))
            stack.callback(self._keeper.close)
            if source is not None:
                stack.callback(source.shutdown)
            bus = source or self._keeper.open_at_start()
            if bus is None:  # stopped while waiting for the bus
                return self._summary()
            self._bus = bus
            self._started = self._last_frame = time.monotonic()
            for ch in self.channels:
                ch.last_frame = self._started
            log.info("up: %s %s → %s", cfg.can.interface, cfg.can.channel,
                     ", ".join(ch.keys.rate for ch in self.channels))
            release_free_heap()  # start-up's temporaries (gyrotherm._memory)
            self._last_trim = time.monotonic()
            self.ready.set()
            self._notifier.ready(status=self._status_line())
            self._loop(process, reopen=source is None)
        return self._summary()

    def _process_for_bus(self) -> Callable[[Any, float], None]:
        """One IMU: its pipeline takes every frame (as always). Several: each frame goes to
        the IMU owning its id; frames of no IMU and transport items are counted here."""
        first = self.channels[0].pipeline
        assert first is not None
        if not self._multi:
            return first.process
        route: dict[int, Callable[[Any, float], None]] = {}
        for i, ch in enumerate(self.channels):
            assert ch.pipeline is not None
            for key in ch.frame_keys():
                route[key] = ch.pipeline.process
            if self.consistency is not None:
                ch.pipeline.rate_tap = self.consistency.tap(i)
        drops = self._bus_drops
        get = route.get

        def process(msg: Any, receive_time_s: float) -> None:
            if type(msg) is TransportItem:
                self._bus_received += 1
                drops[msg.reason] += 1
                return
            try:
                key = msg.arbitration_id + (EXTENDED_KEY if msg.is_extended_id else 0)
            except (AttributeError, TypeError):
                key = -1
            handler = get(key)
            if handler is None:
                self._bus_received += 1
                drops[UNKNOWN_ID] += 1
            else:
                handler(msg, receive_time_s)

        return process

    def _declare_consistency(self, session: zenoh.Session, stack: contextlib.ExitStack) -> None:
        if self.consistency is None:
            return
        prefix = self._consistency_prefix()
        for a, b in self.consistency.pairs:
            pub = session.declare_publisher(
                f"{prefix}/{self.channels[a].sensor}/{self.channels[b].sensor}")
            stack.callback(pub.undeclare)
            self._consistency_pubs.append(pub)

    def _summary(self) -> RunSummary:
        self._log_stop_reason()
        none = Counters(0, 0, 0, 0, {}, 0)
        per_imu = {ch.sensor: ch.pipeline.counters() if ch.pipeline else none
                   for ch in self.channels}
        received = self._bus_received + sum(c.frames_received for c in per_imu.values())
        published = sum(c.frames_published for c in per_imu.values())
        drops: Counter[str] = Counter(self._bus_drops)
        for c in per_imu.values():
            drops.update(c.drops)
        log.info("stopped: %d frames in, %d published, drops %s", received, published,
                 dict(drops))
        if self._multi:
            for name, c in per_imu.items():
                log.info("stopped: %s: %d frames in, %d published, drops %s", name,
                         c.frames_received, c.frames_published, c.drops)
        return RunSummary(received, published, dict(drops), self.reloads,
                          self.reload_failures, time.monotonic() - self._started,
                          per_imu, dict(self._bus_drops))

    def _loop(self, process: Callable[[Any, float], None], *, reopen: bool) -> None:
        now_wall = time.time
        mono = time.monotonic
        cpu = time.thread_time
        timeout = self.config.can.recv_timeout_s
        period = min(ch.config.health_period_s for ch in self.channels)
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
                self._housekeeping()
                if reopen:
                    keeper.tend(self._last_frame, suspect=suspect)
                    suspect = False
                    if keeper.bus is not bus:
                        bus = self._bus = keeper.bus
                        quiet = False

    def _housekeeping(self) -> None:
        self._notifier.watchdog()
        if self._reload.is_set() or self._hup:
            self._reload.clear()
            self._hup = False
            self._reload_all()
        now = time.monotonic()
        for ch in self.channels:
            assert ch.pipeline is not None
            ch.save_effects(ch.pipeline)
            ch.tend_learning(now)
        if now - self._last_trim >= TRIM_PERIOD_S:
            self._last_trim = now
            release_free_heap()
        published = False
        for ch in self.channels:
            assert ch.pipeline is not None
            if self._multi:
                ch.note_frames(now)
            else:
                ch.last_frame = self._last_frame
            if now - ch.last_health >= ch.config.health_period_s:
                silent = now - ch.last_frame > ch.pipeline.stale_after_s or self._bus is None
                ch.publish_health(now, self._started, silent=silent)
                published = True
        if self.consistency is not None:
            from gyrotherm.codecs._wire_consistency import encode_consistency

            for pub, msg in zip(self._consistency_pubs, self.consistency.poll(time.time()),
                                strict=False):
                try:
                    pub.put(encode_consistency(msg))
                except zenoh.ZError as exc:
                    log.warning("consistency publish failed: %s", zenoh_error_text(exc))
        if published:
            self._notifier.status(self._status_line())

    def _reload_all(self) -> None:
        self._notifier.reloading(status="reloading calibration")
        for ch in self.channels:
            assert ch.pipeline is not None
            ch.reload(ch.pipeline, prefix=f"{ch.sensor}: " if self._multi else "")
        self._notifier.ready(status=self._status_line())

    def _do_reload(self, pipeline: Pipeline) -> None:
        """Reload the first IMU's calibration into ``pipeline`` (one-IMU tests)."""
        self._notifier.reloading(status="reloading calibration")
        self.channels[0].reload(pipeline)
        self._notifier.ready(status=self._status_line())

    def _status_line(self) -> str:
        parts = []
        for ch in self.channels:
            p = ch.pipeline
            if p is None:
                return "starting"
            c = p.counters()
            dropped = sum(c.drops.values())
            name = f"{ch.sensor}: " if self._multi else ""
            refused = "; calibration refused" if ch.calibration_error else ""
            if ch.learner is not None:
                refused += f"; {ch.learner.progress.status}"
            parts.append(f"{name}{c.frames_received} frames, {c.frames_published} published, "
                         f"{dropped} dropped; calibration {ch.calibration_id or 'none'}{refused}; "
                         f"flags {p.flags!r}")
        sink = self.channels[0].sink
        zen = ""
        if sink is not None:
            subscribed = "yes" if any(ch.sink and ch.sink.rate_matched for ch in self.channels) \
                else "none"
            zen = f"; zenoh {sink.transports()} transports, rate subscribers {subscribed}"
            episodes = sum(ch.sink.congestion_episodes for ch in self.channels if ch.sink)
            if episodes:
                zen += f", congestion episodes {episodes}"
        if self._bus_received:
            zen += f"; bus: {dict(self._bus_drops)}"
        down = self._keeper.status()
        return " | ".join(parts) + f"{zen}{'; ' + down if down else ''}"
