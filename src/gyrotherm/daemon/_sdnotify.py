"""Dependency-free client of systemd's service notification protocol, sd_notify(3).

Protocol (sd_notify(3), systemd.service(5)):

* The service manager passes ``NOTIFY_SOCKET``: an absolute filesystem path of
  an ``AF_UNIX``/``SOCK_DGRAM`` socket, or ``@name`` for a socket in the
  abstract namespace (the ``@`` stands for a leading NUL byte).
* A notification is ONE datagram of newline-separated ``KEY=VALUE``
  assignments, UTF-8, e.g. ``b"READY=1\\nSTATUS=bus up"``. The manager
  identifies the sender by the kernel-attached credentials (``SCM_CREDENTIALS``),
  so with ``NotifyAccess=main`` it must come from the main PID — any thread of
  the daemon's process qualifies.
* ``WATCHDOG_USEC`` (µs) is the watchdog timeout ``WatchdogSec=``; when
  ``WATCHDOG_PID`` is set, only that PID is meant to answer it. The service must
  send ``WATCHDOG=1`` more often than every ``WATCHDOG_USEC`` µs; systemd
  recommends half of it, which is what :meth:`Notifier.watchdog` enforces.
* ``RELOADING=1`` must carry ``MONOTONIC_USEC=`` (``CLOCK_MONOTONIC`` in µs)
  for ``Type=notify-reload`` (systemd ≥ 253); the service then sends
  ``READY=1`` when the reload is complete.

Contract of :class:`Notifier`:

* Without ``NOTIFY_SOCKET`` every method is a no-op returning ``False``: the
  daemon runs unchanged from a shell or a test.
* :meth:`Notifier.watchdog` is cheap enough to call on every iteration of the
  processing loop: it reads a monotonic clock and sends ``WATCHDOG=1`` only
  when at least half the watchdog interval passed since the previous attempt
  (the first call always sends).
* Sending never raises: an ``OSError`` (socket gone, queue full past
  ``send_timeout_s``) is counted in :attr:`Notifier.send_failures` and kept in
  :attr:`Notifier.last_error`; the method returns ``False``.
* Only :meth:`Notifier.from_environment` raises, with :class:`ConfigError`,
  when a variable is malformed (it runs once, at start-up).
"""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Callable, Mapping
from types import TracebackType

from gyrotherm._errors import ConfigError

__all__ = ["Notifier"]

_NS_PER_S = 1_000_000_000
_NS_PER_US = 1_000


def _monotonic_usec() -> int:
    """``CLOCK_MONOTONIC`` in µs, the clock systemd compares MONOTONIC_USEC= with."""
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC) // _NS_PER_US


def _socket_address(notify_socket: str) -> str:
    """Map a ``NOTIFY_SOCKET`` value to the address ``socket.sendto`` takes.

    ``/path`` stays as is; ``@name`` becomes ``"\\0name"`` (abstract namespace).
    """
    if notify_socket.startswith("@") and len(notify_socket) > 1:
        return "\0" + notify_socket[1:]
    if notify_socket.startswith("/"):
        return notify_socket
    raise ConfigError(
        f"NOTIFY_SOCKET: {notify_socket!r} is neither an absolute path nor an "
        "'@' abstract socket name (other address families are not supported)"
    )


def _single_line(text: str) -> str:
    """STATUS= is one line: CR/LF become spaces, surrounding blanks go."""
    return " ".join(text.replace("\r", "\n").split("\n")).strip()


SEND_TIMEOUT_S = 0.02
"""Default longest wait of one notification on a full socket queue, s. systemd reads
its notify socket at once; a queue that stays full means nobody reads it (a hung or
absent service manager), and the processing loop, which sends from its own thread,
must not stall on it: the notification is dropped and counted instead."""


class Notifier:
    """Sends sd_notify(3) datagrams to the service manager; see the module docstring.

    Build it with :meth:`from_environment` in the daemon; the constructor is
    for tests and for callers that already parsed the environment.
    """

    def __init__(
        self,
        notify_socket: str | None,
        *,
        watchdog_interval_s: float | None = None,
        send_timeout_s: float = SEND_TIMEOUT_S,
        monotonic_ns: Callable[[], int] = time.monotonic_ns,
        monotonic_usec: Callable[[], int] = _monotonic_usec,
    ) -> None:
        """
        Args:
            notify_socket: value of ``NOTIFY_SOCKET`` (``/path`` or ``@name``),
                or ``None`` to disable every notification.
            watchdog_interval_s: the watchdog timeout ``WATCHDOG_USEC`` in s,
                or ``None`` when no watchdog is armed.
            send_timeout_s: how long one send may block on a full receive
                queue before it counts as failed, s (default
                :data:`SEND_TIMEOUT_S`).
            monotonic_ns: clock for the watchdog rate limit, ns (injectable).
            monotonic_usec: ``CLOCK_MONOTONIC`` in µs for ``MONOTONIC_USEC=``.
        """
        if watchdog_interval_s is not None and not watchdog_interval_s > 0.0:
            raise ConfigError(f"watchdog_interval_s: must be > 0 s, got {watchdog_interval_s!r}")
        if not send_timeout_s > 0.0:
            raise ConfigError(f"send_timeout_s: must be > 0 s, got {send_timeout_s!r}")
        self._address = None if notify_socket is None else _socket_address(notify_socket)
        self._watchdog_interval_s = watchdog_interval_s if self._address else None
        self._send_timeout_s = send_timeout_s
        self._monotonic_ns = monotonic_ns
        self._monotonic_usec = monotonic_usec
        self._half_interval_ns = (
            0
            if self._watchdog_interval_s is None
            else int(self._watchdog_interval_s * _NS_PER_S) // 2
        )
        self._last_watchdog_ns: int | None = None
        self._socket: socket.socket | None = None
        self._lock = threading.Lock()
        self._send_failures = 0
        self._sent = 0
        self._last_error: str | None = None

    @classmethod
    def from_environment(
        cls,
        environ: Mapping[str, str] | None = None,
        *,
        pid: int | None = None,
        send_timeout_s: float = SEND_TIMEOUT_S,
    ) -> Notifier:
        """Read ``NOTIFY_SOCKET``, ``WATCHDOG_USEC`` and ``WATCHDOG_PID``.

        Args:
            environ: the environment (default ``os.environ``).
            pid: this process's PID for the ``WATCHDOG_PID`` check
                (default ``os.getpid()``).
            send_timeout_s: see :class:`Notifier`.

        Raises:
            ConfigError: a variable is present but malformed.
        """
        env = os.environ if environ is None else environ
        own_pid = os.getpid() if pid is None else pid
        notify_socket = env.get("NOTIFY_SOCKET") or None
        interval_s: float | None = None
        usec_text = env.get("WATCHDOG_USEC")
        if usec_text:
            try:
                usec = int(usec_text)
            except ValueError as exc:
                raise ConfigError(
                    f"WATCHDOG_USEC: {usec_text!r} is not an integer number of µs"
                ) from exc
            if usec <= 0:
                raise ConfigError(f"WATCHDOG_USEC: must be > 0 µs, got {usec}")
            interval_s = usec / 1e6
            pid_text = env.get("WATCHDOG_PID")
            if pid_text:
                try:
                    watchdog_pid = int(pid_text)
                except ValueError as exc:
                    raise ConfigError(
                        f"WATCHDOG_PID: {pid_text!r} is not an integer process id"
                    ) from exc
                if watchdog_pid != own_pid:
                    interval_s = None  # the watchdog belongs to another process
        return cls(notify_socket, watchdog_interval_s=interval_s, send_timeout_s=send_timeout_s)

    # ------------------------------------------------------------------ state
    @property
    def enabled(self) -> bool:
        """True when ``NOTIFY_SOCKET`` was given: notifications are sent."""
        return self._address is not None

    @property
    def watchdog_interval_s(self) -> float | None:
        """The watchdog timeout (``WATCHDOG_USEC``) in s, ``None`` if not armed."""
        return self._watchdog_interval_s

    @property
    def send_failures(self) -> int:
        """Number of datagrams that could not be sent."""
        return self._send_failures

    @property
    def sent(self) -> int:
        """Number of datagrams sent."""
        return self._sent

    @property
    def last_error(self) -> str | None:
        """Text of the most recent send failure, ``None`` if none happened."""
        return self._last_error

    # --------------------------------------------------------------- messages
    def notify(self, *assignments: str) -> bool:
        """Send ``KEY=VALUE`` assignments in one datagram; True if it was sent."""
        if self._address is None or not assignments:
            return False
        payload = "\n".join(assignments).encode("utf-8")
        with self._lock:
            try:
                if self._socket is None:
                    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
                    sock.settimeout(self._send_timeout_s)
                    self._socket = sock
                self._socket.sendto(payload, self._address)
            except OSError as exc:
                self._send_failures += 1
                self._last_error = f"sending {assignments[0]!r} to NOTIFY_SOCKET failed: {exc}"
                return False
            self._sent += 1
            return True

    def ready(self, *, status: str | None = None) -> bool:
        """``READY=1`` (optionally with ``STATUS=``): start-up or reload finished."""
        if status is None:
            return self.notify("READY=1")
        return self.notify("READY=1", f"STATUS={_single_line(status)}")

    def status(self, text: str) -> bool:
        """``STATUS=<text>``: the one-line summary ``systemctl status`` shows."""
        return self.notify(f"STATUS={_single_line(text)}")

    def watchdog(self) -> bool:
        """``WATCHDOG=1`` when half the interval passed since the last attempt.

        Returns True only when a datagram was sent; a no-op without watchdog.
        """
        if self._watchdog_interval_s is None:
            return False
        now_ns = self._monotonic_ns()
        last_ns = self._last_watchdog_ns
        if last_ns is not None and now_ns - last_ns < self._half_interval_ns:
            return False
        self._last_watchdog_ns = now_ns
        return self.notify("WATCHDOG=1")

    def stopping(self, *, status: str | None = None) -> bool:
        """``STOPPING=1`` (optionally with ``STATUS=``): shutdown has begun."""
        if status is None:
            return self.notify("STOPPING=1")
        return self.notify("STOPPING=1", f"STATUS={_single_line(status)}")

    def reloading(self, *, status: str | None = None) -> bool:
        """``RELOADING=1`` + ``MONOTONIC_USEC=`` (needed by ``Type=notify-reload``).

        Send :meth:`ready` once the reload is done (or rejected).
        """
        assignments = ["RELOADING=1", f"MONOTONIC_USEC={self._monotonic_usec()}"]
        if status is not None:
            assignments.append(f"STATUS={_single_line(status)}")
        return self.notify(*assignments)

    def extend_timeout(self, timeout_s: float) -> bool:
        """``EXTEND_TIMEOUT_USEC=``: ask for ``timeout_s`` more s of start/stop time."""
        return self.notify(f"EXTEND_TIMEOUT_USEC={max(1, round(timeout_s * 1e6))}")

    # -------------------------------------------------------------- lifetime
    def close(self) -> None:
        """Close the socket; later notifications reopen it."""
        with self._lock:
            if self._socket is not None:
                self._socket.close()
                self._socket = None

    def __enter__(self) -> Notifier:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"Notifier(enabled={self.enabled}, watchdog_interval_s={self._watchdog_interval_s}, "
            f"sent={self._sent}, send_failures={self._send_failures})"
        )
