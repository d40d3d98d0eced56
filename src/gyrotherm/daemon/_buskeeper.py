"""The daemon's CAN bus: waited for at start, reopened in the background.

* **Start** (:meth:`BusKeeper.open_at_start`): open attempts with
  :class:`~gyrotherm.daemon._attempt.Backoff` delays (0.1 s doubling to 2 s), one
  log line per failed attempt, until ``[can] start_timeout_s``; then
  :class:`GyrothermError` (the daemon exits 2 and systemd restarts it). A stop
  request ends the wait within :data:`~gyrotherm.daemon._attempt.STOP_POLL_S`,
  also while an attempt hangs (a peer that accepts TCP and never answers).
* **Reopen** (:meth:`BusKeeper.tend`, from the loop's housekeeping): when the
  source says ``link_lost``, when its ``recv`` raises (a CAN interface gone down),
  returns nothing at once or burns CPU instead of waiting (a dead stream peer),
  or when no frame came for
  ``reopen_after_s``, the bus is shut down and reopened by attempts on a worker
  thread with the same backoff. Meanwhile :attr:`BusKeeper.bus` is ``None``: the
  loop waits on an event instead of reading, so it keeps petting the watchdog and
  publishing health (``TEMPERATURE_STALE``: no frames) at almost no CPU.
  Attempts 1, 2, 4, 8 … of an outage are logged.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from gyrotherm._errors import GyrothermError
from gyrotherm.bus import FrameSource, open_bus
from gyrotherm.daemon._attempt import Attempt, Backoff, wait_for
from gyrotherm.daemon._config import CanConfig

log = logging.getLogger("gyrotherm.daemon")

#: An open attempt running this long is reported (once per attempt), s.
SLOW_OPEN_WARN_S = 5.0
_NEVER = threading.Event()  # never set: waiting on it is a pause


def _shutdown(source: FrameSource) -> None:
    source.shutdown()


class BusKeeper:
    """Owns the configured bus; not thread-safe (the daemon's loop thread)."""

    def __init__(self, config: CanConfig, stopping: Callable[[], bool],
                 status: Callable[[str], object] = lambda text: None) -> None:
        self._c = config
        self._stopping = stopping
        self._status = status  # STATUS= while waiting at start (systemctl status)
        self.bus: FrameSource | None = None
        self.reopens = 0
        self.failure: BaseException | None = None  # set by the loop: reading raised this
        self._attempt: Attempt[FrameSource] | None = None
        self._backoff = Backoff()
        self._next_attempt_s = 0.0
        self._attempts = 0  # in the current outage
        self._down_since_s = time.monotonic()
        self._up_since_s = time.monotonic()
        self._slow_warned = False
        c = config
        self.where = f"{c.interface} {c.channel}" + (
            f" at {c.host}:{c.port}" if c.interface == "socketcand" else "")

    def _open(self) -> FrameSource:
        c = self._c
        return open_bus(interface=c.interface, channel=c.channel, bitrate=c.bitrate,
                        host=c.host, port=c.port)

    def _start_attempt(self) -> Attempt[FrameSource]:
        self._attempts += 1
        self._slow_warned = False
        return Attempt(self._open, _shutdown, "gyrotherm-bus-open")

    # --- start ---------------------------------------------------------------------

    def open_at_start(self) -> FrameSource | None:
        """Open the bus, retrying until ``start_timeout_s``; None on a stop request."""
        timeout_s = self._c.start_timeout_s
        deadline = time.monotonic() + timeout_s
        while True:
            attempt = self._start_attempt()
            n = self._attempts
            if not wait_for(attempt.done, self._stopping, deadline - time.monotonic()):
                attempt.abandon()
                if self._stopping():
                    return None
                raise GyrothermError(
                    f"{self.where}: no CAN bus within start_timeout_s = {timeout_s:g} s: "
                    f"attempt {n} got no answer in {time.monotonic() - attempt.started_s:.1f} s"
                    " (a peer that accepts connections but does not answer?)")
            try:
                self.bus = attempt.result()
            except Exception as exc:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise GyrothermError(
                        f"{self.where}: no CAN bus within start_timeout_s = {timeout_s:g} s "
                        f"({n} attempts); last error: {exc}") from exc
                delay = min(self._backoff.next_s(), left)
                log.info("waiting for the bus: attempt %d failed, next in %.1f s: %s",
                         n, delay, exc)
                self._status(f"waiting for the bus {self.where} (attempt {n} failed: {exc})")
                if self._pause(delay):
                    return None
                continue
            if n > 1:
                log.info("bus %s open after %d attempts", self.where, n)
            self._up()
            return self.bus

    def _pause(self, seconds: float) -> bool:
        """Wait ``seconds`` (event waits); True when a stop was requested."""
        wait_for(_NEVER, self._stopping, seconds)
        return self._stopping()

    def _up(self) -> None:
        self._up_since_s = time.monotonic()
        self._attempts = 0
        self._backoff.reset()

    # --- reopen --------------------------------------------------------------------

    def tend(self, last_frame_s: float, *, suspect: bool) -> None:
        """Housekeeping: reopen a lost or silent bus; advance a pending reopen.

        ``suspect``: the loop saw ``recv`` return nothing at once or while burning CPU.
        """
        now = time.monotonic()
        bus = self.bus
        if bus is not None:
            quiet_s = now - max(last_frame_s, self._up_since_s)
            lost = bus.link_lost or suspect
            if lost or quiet_s > self._c.reopen_after_s:
                self.reopens += 1
                why = ("the link is lost" if bus.link_lost else
                       f"reading the bus failed ({self.failure})" if self.failure else
                       "the bus returns no frames without waiting (peer gone?)" if suspect else
                       f"no CAN frame for {self._c.reopen_after_s:.1f} s")
                self.failure = None
                log.warning("%s: reopening %s (reopen %d)", why, self.where, self.reopens)
                self.bus = None
                self._down_since_s = now
                self._next_attempt_s = now
                try:
                    bus.shutdown()
                except Exception as exc:  # a broken bus must not stop the daemon
                    log.warning("shutting down the old bus failed: %s", exc)
            return
        a = self._attempt
        if a is None:
            if now >= self._next_attempt_s:
                self._attempt = self._start_attempt()
            return
        if not a.done.is_set():
            if now - a.started_s > SLOW_OPEN_WARN_S and not self._slow_warned:
                self._slow_warned = True
                log.warning("reopening %s: attempt %d has had no answer for %.0f s "
                            "(a peer that accepts connections but does not answer?)",
                            self.where, self._attempts, now - a.started_s)
            return
        self._attempt = None
        try:
            self.bus = a.result()
        except Exception as exc:  # a failed open must never stop the daemon
            delay = self._backoff.next_s()
            self._next_attempt_s = now + delay
            n = self._attempts
            if n & (n - 1) == 0:
                log.error("reopening %s failed (attempt %d, next in %.1f s; attempts 1, 2, "
                          "4, 8 … are logged): %s", self.where, n, delay, exc)
            return
        log.info("bus %s reopened after %.1f s (%d attempts)", self.where,
                 now - self._down_since_s, self._attempts)
        self._up()

    def status(self) -> str:
        """``""`` while the bus is up, else how long it is down and the attempts."""
        if self.bus is not None:
            return ""
        return (f"bus down {time.monotonic() - self._down_since_s:.0f} s "
                f"(reopen attempt {self._attempts})")

    def close(self) -> None:
        """Shut the bus down and abandon a pending attempt."""
        if self._attempt is not None:
            self._attempt.abandon()
            self._attempt = None
        bus, self.bus = self.bus, None
        if bus is not None:
            bus.shutdown()
