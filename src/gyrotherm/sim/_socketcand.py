"""A socketcand-protocol server: plays simulated CAN frames to other processes over TCP.

The machine has no SocketCAN, so the simulator serves the ASCII protocol of
socketcand (github.com/linux-can/socketcand, ``doc/protocol.md`` and
``state_raw.c``) and the daemon reads it with gyrotherm's own client,
:class:`gyrotherm.bus.SocketcandBus` (python-can's
``can.Bus(interface="socketcand", ...)`` works too).
The session, the ``< frame ID SEC.USEC DATA >`` line and the commands answered
are in :mod:`gyrotherm.sim._socketcand_wire` (classic CAN only; CAN FD, remote
and error frames are rejected with :class:`gyrotherm.DecodeError`); one
connection, and the handshake settle wait (a client joins the broadcast only
once it has read the ``< ok >`` to ``< rawmode >``), in
:mod:`gyrotherm.sim._socketcand_client`; option checks and :class:`ClientStats`
in :mod:`gyrotherm.sim._socketcand_options`; the command line :func:`main` in
:mod:`gyrotherm.sim._socketcand_cli`. Every name of these stays importable from
here.

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

import selectors
import socket
import threading
import time
from collections import deque
from typing import Self

import can

from gyrotherm._errors import ConfigError, DecodeError
from gyrotherm.bus import FrameSink, FrameSource
from gyrotherm.sim._socketcand_cli import main as main
from gyrotherm.sim._socketcand_client import _BATCH_FRAMES as _BATCH_FRAMES
from gyrotherm.sim._socketcand_client import _JOIN_TIMEOUT_S as _JOIN_TIMEOUT_S
from gyrotherm.sim._socketcand_client import _MAX_COMMAND_BYTES as _MAX_COMMAND_BYTES
from gyrotherm.sim._socketcand_client import _QUICKACK as _QUICKACK
from gyrotherm.sim._socketcand_client import _SETTLE_DEADLINE_S as _SETTLE_DEADLINE_S
from gyrotherm.sim._socketcand_client import _SETTLE_FALLBACK_S as _SETTLE_FALLBACK_S
from gyrotherm.sim._socketcand_client import _SETTLE_POLL_S as _SETTLE_POLL_S
from gyrotherm.sim._socketcand_client import _Client as _Client
from gyrotherm.sim._socketcand_client import log as log
from gyrotherm.sim._socketcand_options import ClientStats as ClientStats
from gyrotherm.sim._socketcand_options import _check_endpoint as _check_endpoint
from gyrotherm.sim._socketcand_options import _positive as _positive
from gyrotherm.sim._socketcand_wire import _peer_unread_bytes as _peer_unread_bytes
from gyrotherm.sim._socketcand_wire import _reject as _reject
from gyrotherm.sim._socketcand_wire import demo_frame as demo_frame
from gyrotherm.sim._socketcand_wire import encode_frame as encode_frame
from gyrotherm.sim._socketcand_wire import parse_send as parse_send


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
        _check_endpoint(host, port, channel)
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
            return tuple(
                ClientStats(c.peer, c.connected, c.sent, c.dropped)
                for c in (*self._clients, *self._gone)
            )

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


if __name__ == "__main__":
    raise SystemExit(main())
