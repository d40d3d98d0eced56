"""A socketcand-protocol server: plays simulated CAN frames to other processes over TCP.

The machine has no SocketCAN, so the simulator serves the ASCII protocol of
socketcand (github.com/linux-can/socketcand, ``doc/protocol.md`` and
``state_raw.c``) and the daemon reads it with python-can's own client,
``can.Bus(interface="socketcand", host=..., port=..., channel="vcan0")``.

Session, as python-can's client drives it (every reply is its own TCP write)::

    server: < hi >
    client: < open vcan0 >     server: < ok >       (other channel: error, close)
    client: < rawmode >        server: < ok >
    server: < frame 123 1700000000.000042 0102AB >          (11-bit id: 3 hex digits)
    server: < frame 1ABCDEF0 1700000000.000043  >           (29-bit id: 8 digits, no data)
    client: < send 123 3 1 2 ab >                           (8 id digits: extended)

``< frame ID SEC.USEC DATA >`` carries the message's own ``timestamp`` (seconds,
rounded to the microsecond) and the data as contiguous upper-case hex, exactly
as socketcand prints it. ``< echo >`` is answered with ``< echo >``,
``< bcmmode >`` stops the stream; any other command gets
``< error unknown command >``. Classic CAN only (0–8 data bytes, standard and
extended ids); CAN FD, remote and error frames are rejected with
:class:`gyrotherm.DecodeError`.

Handshake race: python-can reads ``< ok >`` with one ``recv`` and compares it
whole, so a frame arriving before that read would break its handshake (not
seen in testing, but nothing in the protocol prevents it). After
``< ok >`` to ``< rawmode >`` the server therefore waits (at most 2 s) until the
peer's socket has no unread bytes, read from ``/proc/net/tcp`` when the peer is
on this host, else for a fixed 50 ms; only then does the client join the
broadcast and count in :meth:`SocketcandServer.wait_for_clients`.

Back-pressure: :meth:`SocketcandServer.send` never blocks. Each client has a
bounded queue (``client_queue_frames``) emptied by its own writer thread; when
it is full the new frame is dropped for that client (tail drop, as a full
SocketCAN receive buffer does) and counted in :class:`ClientStats`.
Frames clients send are queued (bounded, ``rx_queue_frames``) for
:meth:`SocketcandServer.recv` and relayed to the other raw-mode clients, as
nodes on one bus see each other's frames.

Run ``python -m gyrotherm.sim._socketcand --port 0 --frames N``: prints the
bound port on stdout, waits for a client, plays ``N`` :func:`demo_frame` frames.
"""

from __future__ import annotations

import argparse
import logging
import math
import selectors
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Self

import can

from gyrotherm._errors import ConfigError, DecodeError
from gyrotherm.sim._bus import FrameSink, FrameSource

log = logging.getLogger(__name__)

_BATCH_FRAMES = 2048  # frames joined into one sendall by a writer thread
_MAX_COMMAND_BYTES = 4096  # an unterminated command longer than this closes the client
_SETTLE_DEADLINE_S = 2.0
_SETTLE_FALLBACK_S = 0.05
_SETTLE_POLL_S = 0.0005
_JOIN_TIMEOUT_S = 2.0
_QUICKACK: int | None = getattr(socket, "TCP_QUICKACK", None)  # Linux only


@dataclass(frozen=True)
class ClientStats:
    """Counters of one client connection (``peer`` is ``"host:port"``)."""

    peer: str
    connected: bool
    frames_sent: int
    frames_dropped: int


def _reject(msg: can.Message, why: str) -> DecodeError:
    return DecodeError(f"frame 0x{msg.arbitration_id:X}: cannot be sent over socketcand: {why}")


def encode_frame(msg: can.Message) -> bytes:
    """The ``< frame ID SEC.USEC DATA >`` line for a classic CAN frame."""
    arb, data = msg.arbitration_id, msg.data
    if msg.is_fd or msg.is_remote_frame or msg.is_error_frame:
        raise _reject(msg, "only classic data frames are supported (no FD, remote, error)")
    if len(data) > 8 or msg.dlc != len(data):
        raise _reject(msg, f"dlc {msg.dlc} with {len(data)} data bytes, limit 0..8 and equal")
    if msg.is_extended_id:
        if not 0 <= arb <= 0x1FFFFFFF:
            raise _reject(msg, "extended id outside 0..0x1FFFFFFF")
        ident = f"{arb:08X}"
    else:
        if not 0 <= arb <= 0x7FF:
            raise _reject(msg, "standard id outside 0..0x7FF")
        ident = f"{arb:03X}"
    ts = msg.timestamp
    if not (ts >= 0.0 and math.isfinite(ts)):
        raise _reject(msg, f"timestamp {ts!r} s, must be finite and >= 0")
    sec, usec = divmod(round(ts * 1_000_000), 1_000_000)
    return f"< frame {ident} {sec}.{usec:06d} {data.hex().upper()} >".encode("ascii")


def parse_send(command: str, *, channel: str, timestamp_s: float) -> can.Message:
    """Decode ``< send ID DLC B0 B1 ... >`` (hex fields; 8 id digits: extended id)."""
    words = command.strip("<> \t\r\n").split()
    try:
        if len(words) < 3 or words[0] != "send":
            raise ValueError("expected '< send can_id can_dlc [data]* >'")
        ident, dlc, payload = words[1], int(words[2], 16), words[3:]
        extended = len(ident) == 8
        arb = int(ident, 16)
        if arb > (0x1FFFFFFF if extended else 0x7FF) or arb < 0:
            raise ValueError(
                f"id {ident} out of range for {'extended' if extended else 'standard'}"
            )
        if not 0 <= dlc <= 8 or len(payload) != dlc:
            raise ValueError(f"dlc {dlc} with {len(payload)} data bytes, limit 0..8 and equal")
        data = bytes(int(b, 16) for b in payload)
    except ValueError as exc:
        raise DecodeError(f"socketcand command {command!r}: {exc}") from exc
    return can.Message(
        timestamp=timestamp_s,
        arbitration_id=arb,
        is_extended_id=extended,
        data=data,
        is_rx=True,
        channel=channel,
    )


def demo_frame(index: int) -> can.Message:
    """Deterministic test frame ``index`` (what ``--frames N`` plays).

    Odd ``index``: extended id ``0x1ABC0000 + index``; even: standard id
    ``index % 0x800``. Data: ``index % 9`` bytes ``(index + k) % 256``. Timestamp:
    ``1_700_000_000 s + index ms + (index % 1000) µs``.
    """
    extended = index % 2 == 1
    arb = (0x1ABC0000 + index) & 0x1FFFFFFF if extended else index % 0x800
    data = bytes((index + k) % 256 for k in range(index % 9))
    ts_us = 1_700_000_000_000_000 + 1_000 * index + index % 1_000
    return can.Message(
        timestamp=ts_us / 1e6, arbitration_id=arb, is_extended_id=extended, data=data
    )


def _peer_unread_bytes(server_port: int, client_port: int) -> int | None:
    """Bytes the server sent that the local peer has not read yet, or None if unknown."""
    ours = theirs = None
    for path in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(path, encoding="ascii") as table:
                rows = table.read().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            f = row.split()
            if len(f) < 5 or f[3] != "01":  # 01: ESTABLISHED
                continue
            local, remote = int(f[1].rsplit(":", 1)[1], 16), int(f[2].rsplit(":", 1)[1], 16)
            tx_queue, rx_queue = (int(q, 16) for q in f[4].split(":"))
            if (local, remote) == (server_port, client_port):
                ours = tx_queue  # sent but not yet acknowledged by the peer's kernel
            elif (local, remote) == (client_port, server_port):
                theirs = rx_queue  # received by the peer's kernel, not yet read
    if theirs is None:
        return None
    return theirs + (ours or 0)


class _Client:
    """One TCP connection: a reader thread (commands) and a writer thread (frames)."""

    def __init__(self, server: SocketcandServer, sock: socket.socket, peer: str) -> None:
        self.peer = peer
        self.sent = 0
        self.dropped = 0
        self.connected = True
        self._server, self._sock = server, sock
        self._queue: deque[bytes] = deque()
        self._lock = threading.Lock()  # guards _queue, _idle, _closing, dropped
        self._send_lock = threading.Lock()  # one writer on the socket at a time
        self._wake = threading.Event()
        self._idle = True  # writer waits and holds no batch
        self._closing = False
        self._opened = False  # "< open CHANNEL >" accepted
        self._raw = False  # "< rawmode >" accepted and settled
        self._reader = threading.Thread(
            target=self._read_loop, name=f"socketcand<{peer}", daemon=True
        )
        self._writer = threading.Thread(
            target=self._write_loop, name=f"socketcand>{peer}", daemon=True
        )

    def start(self) -> None:
        self._writer.start()
        self._reader.start()

    @property
    def drained(self) -> bool:
        return self._idle and not self._queue

    def stats(self) -> ClientStats:
        return ClientStats(self.peer, self.connected, self.sent, self.dropped)

    def enqueue(self, line: bytes) -> None:
        with self._lock:
            if len(self._queue) >= self._server.client_queue_frames:
                self.dropped += 1
                return
            self._queue.append(line)
            if self._idle:
                self._idle = False
                self._wake.set()

    def close(self) -> None:
        """Stop both threads; the reader closes the socket once the writer is done."""
        with self._lock:
            self._closing = True
            self._wake.set()
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def join(self, timeout_s: float) -> None:
        self._reader.join(timeout_s)

    def _send_now(self, data: bytes) -> bool:
        with self._send_lock:
            try:
                self._sock.sendall(data)
            except OSError:
                return False
        return True

    def _write_loop(self) -> None:
        while True:
            with self._lock:
                closing = self._closing
                if self._queue and not closing:
                    q = self._queue
                    if len(q) <= _BATCH_FRAMES:
                        batch = list(q)
                        q.clear()
                    else:
                        batch = [q.popleft() for _ in range(_BATCH_FRAMES)]
                else:
                    batch = []
                    self._queue.clear()
                    self._idle = True
                    self._wake.clear()
            if not batch:
                self._server._notify()
                if closing:
                    return
                self._wake.wait()
            elif self._send_now(b"".join(batch)):
                self.sent += len(batch)
            else:
                self.close()

    def _read_loop(self) -> None:
        try:
            if self._send_now(b"< hi >"):
                self._serve_commands()
        except OSError:
            pass
        finally:
            self.connected = False
            self._server._forget(self)
            self.close()
            self._writer.join(_JOIN_TIMEOUT_S)
            self._sock.close()

    def _serve_commands(self) -> None:
        buf = b""
        while chunk := self._sock.recv(4096):
            if _QUICKACK is not None:  # as socketcand: ack now, so Nagle does not stall the peer
                self._sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
            buf += chunk
            while (start := buf.find(b"<")) >= 0 and (end := buf.find(b">", start)) >= 0:
                command, buf = buf[start : end + 1].decode("ascii", "replace"), buf[end + 1 :]
                if not self._handle(command):
                    return
            buf = buf[start:] if start >= 0 else b""  # drop bytes outside "< ... >"
            if len(buf) > _MAX_COMMAND_BYTES:
                log.warning(
                    "socketcand client %s: command longer than %d bytes",
                    self.peer,
                    _MAX_COMMAND_BYTES,
                )
                return

    def _handle(self, command: str) -> bool:
        """Answer one command; False closes the connection."""
        words = command[1:-1].split()
        verb = words[0] if words else ""
        if not self._opened:
            if verb == "open" and len(words) == 2 and words[1] == self._server.channel:
                self._opened = True
                return self._send_now(b"< ok >")
            if verb == "open":
                self._send_now(b"< error could not open bus >")
                return False
        elif verb == "send":
            self._server._client_frame(self, command)
            return True
        elif verb == "echo":
            return self._send_now(b"< echo >")
        elif verb == "rawmode":
            ok = self._send_now(b"< ok >")
            if ok and not self._raw:
                self._raw = True
                self._await_consumed()
                self._server._activate(self)
            return ok
        elif verb == "bcmmode":
            self._raw = False
            self._server._deactivate(self)
            return self._send_now(b"< ok >")
        return self._send_now(b"< error unknown command >")

    def _await_consumed(self) -> None:
        """Wait until the peer has read everything sent so far (see the module docstring)."""
        server_port, client_port = self._sock.getsockname()[1], self._sock.getpeername()[1]
        deadline = time.monotonic() + _SETTLE_DEADLINE_S
        stopping = self._server._stopping
        while True:
            unread = _peer_unread_bytes(server_port, client_port)
            if unread is None:
                stopping.wait(_SETTLE_FALLBACK_S)
                return
            if unread == 0 or time.monotonic() >= deadline or stopping.wait(_SETTLE_POLL_S):
                return


def _positive(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{name}: must be an integer >= 1, got {value!r}")
    return value


class SocketcandServer(FrameSource, FrameSink):
    """Threaded socketcand server on ``host``:``port`` serving one channel.

    ``send`` broadcasts to every client in raw mode (never blocks; drops per
    client when its queue is full); ``recv`` returns frames clients sent. Listens
    on 127.0.0.1 unless ``host`` says otherwise; ``port=0`` picks a free port,
    read :attr:`port` after :meth:`start`. A context manager (starts on enter);
    :meth:`shutdown` is idempotent, discards queued frames (call :meth:`flush`
    first) and closes every client socket.
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        channel: str = "vcan0",
        client_queue_frames: int = 65_536,
        rx_queue_frames: int = 65_536,
        max_clients: int = 16,
        relay_between_clients: bool = True,
        client_sndbuf_bytes: int | None = None,
    ) -> None:
        if not isinstance(host, str) or not host:
            raise ConfigError(f"host: must be a non-empty address, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ConfigError(f"port: must be an integer in 0..65535 (0: ephemeral), got {port!r}")
        if not isinstance(channel, str) or not 0 < len(channel) <= 16 or " " in channel:
            raise ConfigError(
                f"channel: must be 1 to 16 characters without spaces, got {channel!r}"
            )
        self.host, self.channel = host, channel
        self.client_queue_frames = _positive("client_queue_frames", client_queue_frames)
        self._rx_limit = _positive("rx_queue_frames", rx_queue_frames)
        self._max_clients = _positive("max_clients", max_clients)
        self._relay = relay_between_clients
        self._sndbuf = (
            None
            if client_sndbuf_bytes is None
            else _positive("client_sndbuf_bytes", client_sndbuf_bytes)
        )
        self._requested_port = port
        self._listener: socket.socket | None = None
        self._accept_thread: threading.Thread | None = None
        self._wake: tuple[socket.socket, socket.socket] | None = None  # wakes the accept loop
        self._stopping = threading.Event()
        self._changed = threading.Condition()  # guards the client lists and _closed
        self._clients: list[_Client] = []
        self._active: tuple[_Client, ...] = ()  # raw mode, settled: receive broadcasts
        self._gone: deque[_Client] = deque(maxlen=64)
        self._closed = False
        self._rx: deque[can.Message] = deque()
        self._rx_cond = threading.Condition()
        self.rx_dropped = 0
        """Client frames dropped because the ``recv`` queue was full."""
        self.rx_errors = 0
        """Malformed ``< send >`` commands (logged and ignored, as socketcand does)."""

    # -- lifetime ---------------------------------------------------------------
    def start(self) -> Self:
        """Bind, listen and accept clients in a background thread; returns self."""
        with self._changed:
            if self._closed:
                raise RuntimeError("SocketcandServer: already shut down, cannot start again")
            if self._listener is not None:
                return self
            family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
            listener = socket.socket(family, socket.SOCK_STREAM)
            try:
                listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                listener.bind((self.host, self._requested_port))
                listener.listen(16)
            except OSError as exc:
                listener.close()
                raise ConfigError(
                    f"host/port: cannot listen on {self.host}:{self._requested_port}: {exc}"
                ) from exc
            self._listener, self._wake = listener, socket.socketpair()
            self._accept_thread = threading.Thread(
                target=self._accept_loop, name="socketcand-accept", daemon=True
            )
            self._accept_thread.start()
        return self

    def __enter__(self) -> Self:
        return self.start()

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port) (after :meth:`start`)."""
        if self._listener is None:
            raise RuntimeError("SocketcandServer: not started, no port bound yet")
        host, port = self._listener.getsockname()[:2]
        return str(host), int(port)

    @property
    def port(self) -> int:
        """The bound TCP port (after :meth:`start`)."""
        return self.address[1]

    @property
    def is_shutdown(self) -> bool:
        return self._closed

    def shutdown(self) -> None:
        with self._changed:
            if self._closed:
                return
            self._closed = True
            clients, self._active = list(self._clients), ()
            self._changed.notify_all()
        self._stopping.set()
        if self._wake is not None:
            self._wake[1].send(b"!")
        if self._accept_thread is not None:
            self._accept_thread.join(_JOIN_TIMEOUT_S)
        if self._listener is not None:
            self._listener.close()
        for end in self._wake or ():
            end.close()
        for client in clients:
            client.close()
        for client in clients:
            client.join(_JOIN_TIMEOUT_S)
        with self._rx_cond:
            self._rx_cond.notify_all()

    # -- frames -----------------------------------------------------------------
    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        """Broadcast ``msg`` to the raw-mode clients (``timeout_s`` unused: never blocks).

        Raises :class:`gyrotherm.DecodeError` for a frame socketcand cannot carry.
        After :meth:`shutdown` frames are discarded.
        """
        line = encode_frame(msg)
        for client in self._active:
            client.enqueue(line)

    def recv(self, timeout_s: float | None = None) -> can.Message | None:
        """Next frame a client sent, or None after ``timeout_s`` s or once shut down."""
        with self._rx_cond:
            self._rx_cond.wait_for(lambda: self._rx or self._closed, timeout_s)
            return self._rx.popleft() if self._rx else None

    def wait_for_clients(self, n: int, timeout_s: float | None) -> bool:
        """Wait until at least ``n`` clients are streaming (raw mode); False on timeout."""
        with self._changed:
            return self._changed.wait_for(lambda: len(self._active) >= n, timeout_s)

    def wait_until_disconnected(self, timeout_s: float | None, *, remaining: int = 0) -> bool:
        """Wait until at most ``remaining`` clients are connected; False on timeout."""
        with self._changed:
            return self._changed.wait_for(lambda: len(self._clients) <= remaining, timeout_s)

    def flush(self, timeout_s: float | None) -> bool:
        """Wait until every streaming client's queue is written to its socket; False on timeout."""
        with self._changed:
            return self._changed.wait_for(lambda: all(c.drained for c in self._active), timeout_s)

    @property
    def client_count(self) -> int:
        """Clients currently streaming (raw mode, handshake settled)."""
        return len(self._active)

    def client_stats(self) -> tuple[ClientStats, ...]:
        """Counters of connected clients, then of the last 64 that disconnected."""
        with self._changed:
            return tuple(c.stats() for c in (*self._clients, *self._gone))

    # -- called by client threads -------------------------------------------------
    def _notify(self) -> None:
        with self._changed:
            self._changed.notify_all()

    def _activate(self, client: _Client) -> None:
        with self._changed:
            if not self._closed and client in self._clients and client not in self._active:
                self._active = (*self._active, client)
                self._changed.notify_all()

    def _deactivate(self, client: _Client) -> None:
        with self._changed:
            self._active = tuple(c for c in self._active if c is not client)
            self._changed.notify_all()

    def _forget(self, client: _Client) -> None:
        with self._changed:
            self._active = tuple(c for c in self._active if c is not client)
            if client in self._clients:
                self._clients.remove(client)
                self._gone.append(client)
            self._changed.notify_all()

    def _client_frame(self, client: _Client, command: str) -> None:
        try:
            msg = parse_send(command, channel=self.channel, timestamp_s=time.time())
        except DecodeError as exc:
            with self._rx_cond:
                self.rx_errors += 1
            log.warning("socketcand client %s: %s", client.peer, exc)
            return
        with self._rx_cond:
            if len(self._rx) >= self._rx_limit:
                self.rx_dropped += 1
            else:
                self._rx.append(msg)
                self._rx_cond.notify()
        if self._relay:
            line = encode_frame(msg)
            for other in self._active:
                if other is not client:
                    other.enqueue(line)

    def _accept_loop(self) -> None:
        listener, wake = self._listener, self._wake
        assert listener is not None and wake is not None
        with selectors.DefaultSelector() as selector:
            selector.register(listener, selectors.EVENT_READ)
            selector.register(wake[0], selectors.EVENT_READ)
            while not any(key.fileobj is wake[0] for key, _ in selector.select()):
                self._accept_one(listener)

    def _accept_one(self, listener: socket.socket) -> None:
        try:
            conn, addr = listener.accept()
        except OSError:
            return
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self._sndbuf is not None:
            conn.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self._sndbuf)
        client = _Client(self, conn, f"{addr[0]}:{addr[1]}")
        with self._changed:
            accepted = not self._closed and len(self._clients) < self._max_clients
            if accepted:
                self._clients.append(client)
        if accepted:
            client.start()
            return
        log.warning("socketcand: refusing %s (limit %d clients)", client.peer, self._max_clients)
        try:
            conn.sendall(b"< error too many clients >")
        except OSError:
            pass
        conn.close()


def main(argv: Sequence[str] | None = None) -> int:
    """Serve a socketcand channel; with ``--frames N`` play N demo frames, then exit."""
    parser = argparse.ArgumentParser(
        prog="python -m gyrotherm.sim._socketcand", description=main.__doc__
    )
    parser.add_argument("--host", default="127.0.0.1", help="listen address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=0, help="TCP port (default 0: ephemeral)")
    parser.add_argument("--channel", default="vcan0", help="channel name served (default vcan0)")
    parser.add_argument("--frames", type=int, default=None, help="play N demo frames, then exit")
    parser.add_argument("--clients", type=int, default=1, help="clients to wait for (default 1)")
    parser.add_argument("--timeout-s", type=float, default=30.0, help="wait limit (default 30 s)")
    args = parser.parse_args(argv)
    try:
        server = SocketcandServer(host=args.host, port=args.port, channel=args.channel).start()
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with server:
        print(server.port, flush=True)
        if args.frames is None:
            try:
                threading.Event().wait()
            except KeyboardInterrupt:
                return 0
        if not server.wait_for_clients(args.clients, args.timeout_s):
            print(
                f"error: fewer than {args.clients} clients within {args.timeout_s} s",
                file=sys.stderr,
            )
            return 3
        chunk = min(1024, server.client_queue_frames)
        for first in range(0, args.frames, chunk):
            for index in range(first, min(first + chunk, args.frames)):
                server.send(demo_frame(index))
            if not server.flush(args.timeout_s):
                print(f"error: clients did not read within {args.timeout_s} s", file=sys.stderr)
                return 4
        server.wait_until_disconnected(args.timeout_s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
