"""One socketcand client connection of the server: a reader and a writer thread.

The reader thread sends ``< hi >`` and answers the client's commands
(:mod:`gyrotherm.sim._socketcand_wire` has the protocol); the writer thread
empties the client's bounded queue onto the socket, up to 2048 frames per
``sendall``. :meth:`_Client.enqueue` never blocks: when the queue holds
``client_queue_frames`` lines the new frame is dropped for this client (tail
drop, as a full SocketCAN receive buffer does) and counted.

Handshake race: python-can reads ``< ok >`` with one ``recv`` and compares it
whole, so a frame arriving before that read would break its handshake (not
seen in testing, but nothing in the protocol prevents it). After
``< ok >`` to ``< rawmode >`` the server therefore waits (at most 2 s) until the
peer's socket has no unread bytes, read from ``/proc/net/tcp`` when the peer is
on this host, else for a fixed 50 ms; only then does the client join the
broadcast and count in :meth:`SocketcandServer.wait_for_clients`.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from typing import TYPE_CHECKING

from gyrotherm.sim._socketcand_wire import _peer_unread_bytes

if TYPE_CHECKING:
    from gyrotherm.sim._socketcand import SocketcandServer

log = logging.getLogger("gyrotherm.sim._socketcand")  # one logger for the whole server

_BATCH_FRAMES = 2048  # frames joined into one sendall by a writer thread
_MAX_COMMAND_BYTES = 4096  # an unterminated command longer than this closes the client
_SETTLE_DEADLINE_S = 2.0
_SETTLE_FALLBACK_S = 0.05
_SETTLE_POLL_S = 0.0005
_JOIN_TIMEOUT_S = 2.0
_QUICKACK: int | None = getattr(socket, "TCP_QUICKACK", None)  # Linux only


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
