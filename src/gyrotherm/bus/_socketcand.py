"""gyrotherm's own socketcand client: a :class:`FrameSource` and :class:`FrameSink`.

:func:`gyrotherm.bus.open_bus` returns a :class:`SocketcandBus` for
``interface="socketcand"`` (python-can's client is no longer involved: it died
on malformed server text, hung on a silent peer and spun on a closed one).

Contract:

* **Handshake** (:meth:`SocketcandBus.connect`): ``< hi >``, ``< open CH >`` →
  ``< ok >``, ``< rawmode >`` → ``< ok >``, all within ``handshake_timeout_s``
  (connect included). A refused or unreachable port raises
  :class:`gyrotherm.ConfigError`; a peer that stays silent, says something else
  or closes raises :class:`gyrotherm.BusError` naming host:port, the channel,
  what was expected and what was received. Bytes after the last ``< ok >`` are
  kept (frames may follow at once).
* **recv(timeout_s)** returns a :class:`can.Message`, a :class:`TransportItem` or
  ``None`` once ``timeout_s`` passed; it never raises on anything the peer sends.
  Each item that is not a valid frame is exactly one :class:`TransportItem` with
  reason :data:`TRANSPORT_MALFORMED`, :data:`TRANSPORT_ERROR` or
  :data:`TRANSPORT_OTHER` (rules in :mod:`gyrotherm.bus._socketcand_items`).
  Reads are 64 KiB; the pending partial item is at most 4096 bytes.
* **Link loss** (peer closed, reset, socket error): :attr:`link_lost` becomes
  True (a partial item pending then is one malformed item), items already read
  are still returned, then ``recv`` waits its whole timeout (on an event, no busy
  loop) and returns ``None``. The owner shuts the bus down and opens a new one.
* **Logging**: per reason, occurrences 1, 2, 4, 8 … are logged at WARNING (the
  count and the offending bytes, quoted and bounded), so 10^6 items of one reason
  give at most 20 lines, all three reasons at most 60. A lost link logs once.
  :attr:`counts` holds every reason's total.
* **send(msg, timeout_s)**: ``< send ID DLC B0 … >`` as python-can writes it
  (8 id digits: extended); blocks at most ``timeout_s`` (``None``:
  :data:`SEND_TIMEOUT_S`), raises :class:`gyrotherm.BusError` on timeout or a
  lost link.

Not thread-safe for two concurrent readers; ``send`` and ``shutdown`` may be
called from other threads.
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections import Counter, deque

import can

from gyrotherm._errors import BusError, ConfigError
from gyrotherm.bus._bus import FrameSink, FrameSource, TransportItem
from gyrotherm.bus._socketcand_items import (
    MAX_ITEM_BYTES,
    TRANSPORT_ERROR,
    TRANSPORT_MALFORMED,
    TRANSPORT_OTHER,
    ItemSplitter,
    Result,
    quote,
)

__all__ = ["TRANSPORT_ERROR", "TRANSPORT_MALFORMED", "TRANSPORT_OTHER", "SocketcandBus"]

log = logging.getLogger("gyrotherm.bus.socketcand")

HANDSHAKE_TIMEOUT_S = 2.0
"""Default bound of connect + handshake, s."""
SEND_TIMEOUT_S = 1.0
"""Default bound of one ``send``, s."""
READ_BYTES = 65_536
_WAIT_SLICE_S = 0.25  # recv(None) re-checks shutdown this often
_READ_EVENTS = select.POLLIN | select.POLLPRI | select.POLLERR | select.POLLHUP


class SocketcandBus(FrameSource, FrameSink):
    """One socketcand connection in raw mode; open it with :meth:`connect`."""

    def __init__(self, sock: socket.socket, host: str, port: int, channel: str,
                 rest: bytes = b"") -> None:
        """Wrap a socket that finished the handshake (``rest``: bytes read after it)."""
        self.host, self.port, self.channel = host, port, channel
        self.where = f"socketcand {host}:{port} channel {channel!r}"
        self._sock = sock
        sock.setblocking(False)
        self._poll = select.poll()
        self._poll.register(sock.fileno(), _READ_EVENTS)
        self._buf = bytearray(READ_BYTES)
        self._view = memoryview(self._buf)
        self._splitter = ItemSplitter(channel)
        self._ready: deque[Result] = deque()
        self._lost = False
        self._closed = threading.Event()
        self._send_lock = threading.Lock()
        self.counts: Counter[str] = Counter()
        """Transport items returned so far, by reason."""
        if rest:
            self._take(rest)

    @classmethod
    def connect(cls, host: str, port: int, channel: str, *,
                handshake_timeout_s: float = HANDSHAKE_TIMEOUT_S) -> SocketcandBus:
        """Connect and run the handshake within ``handshake_timeout_s`` (see module doc)."""
        where = f"socketcand {host}:{port} channel {channel!r}"
        t = handshake_timeout_s
        deadline = time.monotonic() + t
        try:
            sock = socket.create_connection((host, port), timeout=handshake_timeout_s)
        except OSError as exc:
            raise ConfigError(f"interface 'socketcand', channel {channel!r} at {host}:{port}: "
                              f"cannot open the bus ({exc})") from exc
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            buf = _expect(sock, b"", b"< hi >", "on connecting", where, deadline, t)
            sock.sendall(f"< open {channel} >".encode("ascii"))
            buf = _expect(sock, buf, b"< ok >", f"to '< open {channel} >'", where, deadline, t)
            sock.sendall(b"< rawmode >")
            buf = _expect(sock, buf, b"< ok >", "to '< rawmode >'", where, deadline, t)
        except OSError as exc:  # timeouts of sendall, resets
            sock.close()
            raise BusError(f"{where}: handshake failed: {exc}") from exc
        except BaseException:
            sock.close()
            raise
        return cls(sock, host, port, channel, buf)

    # -- FrameSource ------------------------------------------------------------
    @property
    def is_shutdown(self) -> bool:
        return self._closed.is_set()

    @property
    def link_lost(self) -> bool:
        return self._lost

    def recv(self, timeout_s: float | None = None) -> can.Message | TransportItem | None:
        ready = self._ready
        if ready:
            item = ready.popleft()
            if type(item) is TransportItem:
                self._count(item)
            return item
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while not self._lost and not self._closed.is_set():
            try:
                n = self._sock.recv_into(self._buf)
            except BlockingIOError:
                left = _WAIT_SLICE_S if deadline is None else deadline - time.monotonic()
                if left <= 0:
                    return None
                self._poll.poll(1000 * min(left, _WAIT_SLICE_S) + 1)
                continue
            except OSError as exc:  # reset, or closed by shutdown()
                self._lose(f"{type(exc).__name__}: {exc}")
                break
            if n == 0:
                self._lose("the peer closed the connection")
                break
            self._take(self._view[:n].tobytes())
            if ready:
                break
        if ready:
            item = ready.popleft()
            if type(item) is TransportItem:
                self._count(item)
            return item
        if deadline is None:
            self._closed.wait()
        else:
            self._closed.wait(max(0.0, deadline - time.monotonic()))
        return None

    def _take(self, chunk: bytes) -> None:
        out: list[Result] = []
        self._splitter.feed(chunk, out)
        self._ready.extend(out)

    def _count(self, item: TransportItem) -> None:
        counts = self.counts
        counts[item.reason] += 1
        n = counts[item.reason]
        if n & (n - 1) == 0:  # occurrences 1, 2, 4, 8 … are logged
            log.warning("%s: %s #%d (occurrences 1, 2, 4, 8 … are logged): %s",
                        self.where, item.reason, n, item.detail)

    def _lose(self, why: str) -> None:
        if not self._lost and not self._closed.is_set():
            log.warning("%s: link lost: %s", self.where, why)
        self._lost = True
        out: list[Result] = []
        self._splitter.close(out)
        self._ready.extend(out)

    # -- FrameSink --------------------------------------------------------------
    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        """Write ``< send ID DLC B0 … >``; :class:`BusError` if not written in time."""
        arb = msg.arbitration_id
        ident = f"{arb & 0x1FFFFFFF:08X}" if msg.is_extended_id else f"{arb & 0x7FF:03X}"
        data = bytes(msg.data[: msg.dlc])
        line = f"< send {ident} {len(data):X} {' '.join(f'{b:x}' for b in data)} >"
        wait_s = SEND_TIMEOUT_S if timeout_s is None else timeout_s
        deadline = time.monotonic() + wait_s
        view = memoryview(line.encode("ascii"))
        with self._send_lock:
            while view:
                if self._closed.is_set() or self._lost:
                    raise BusError(f"{self.where}: cannot send {line!r}: the link is "
                                   f"{'shut down' if self._closed.is_set() else 'lost'}")
                try:
                    view = view[self._sock.send(view):]
                except BlockingIOError:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        raise BusError(f"{self.where}: cannot send {line!r}: the peer "
                                       f"accepted nothing for {wait_s:g} s") from None
                    select.select([], [self._sock], [], min(left, _WAIT_SLICE_S))
                except OSError as exc:
                    self._lose(f"{type(exc).__name__}: {exc}")
                    raise BusError(f"{self.where}: cannot send {line!r}: {exc}") from exc

    def shutdown(self) -> None:
        if self._closed.is_set():
            return
        self._closed.set()
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()

    def __repr__(self) -> str:
        return f"SocketcandBus({self.host!r}, {self.port}, {self.channel!r})"


def _expect(sock: socket.socket, buf: bytes, want: bytes, when: str, where: str,
            deadline: float, timeout_s: float) -> bytes:
    """Read one handshake item; it must be ``want``. Returns the bytes after it."""
    while (end := buf.find(b">")) < 0:
        left = deadline - time.monotonic()
        if left <= 0 or len(buf) > MAX_ITEM_BYTES:
            why = "no answer" if not buf.strip() else "no complete '< … >' item"
            raise BusError(f"{where}: handshake: expected {want.decode()!r} {when}, got {why}"
                           f" within handshake_timeout_s = {timeout_s:g} s"
                           f" (received {quote(buf)})")
        sock.settimeout(left)
        try:
            chunk = sock.recv(MAX_ITEM_BYTES)
        except TimeoutError:
            continue
        except ConnectionResetError:  # it closed before reading what we sent: a reset, not EOF
            chunk = b""
        if not chunk:
            raise BusError(f"{where}: handshake: expected {want.decode()!r} {when}, but the "
                           f"peer closed the connection (received {quote(buf)})")
        buf += chunk
    item, rest = buf[: end + 1].strip(), buf[end + 1 :]
    if item != want:
        raise BusError(f"{where}: handshake: expected {want.decode()!r} {when}, "
                       f"got {quote(item)}")
    return rest
