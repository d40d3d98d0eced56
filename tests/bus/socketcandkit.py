"""A hand-written hostile socketcand peer for the reader's tests (127.0.0.1, port 0).

:class:`HostilePeer` accepts connections in a thread. A connection that closes
before saying ``< open … >`` (the port probe of ``open_bus``) is forgotten; on
the first one that opens, it plays the handshake as scripted (``hi``,
``open_reply``, ``raw_reply``; ``None`` stays silent from that step on), then
writes each of ``chunks`` with its own ``sendall`` (TCP_NODELAY), sets
:attr:`sent` and keeps the connection until :meth:`vanish` (close) or
:meth:`close`. Synchronisation is by events with timeouts, never sleeps.
"""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Sequence

WAIT_S = 10.0


class HostilePeer:
    def __init__(
        self,
        chunks: Sequence[bytes] = (),
        *,
        hi: bytes | None = b"< hi >",
        open_reply: bytes | None = b"< ok >",
        raw_reply: bytes | None = b"< ok >",
    ) -> None:
        self.chunks, self.hi = list(chunks), hi
        self.open_reply, self.raw_reply = open_reply, raw_reply
        self.received = b""
        self.sent = threading.Event()
        self.accepted = threading.Event()
        self._vanish = threading.Event()
        self._reset = False
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._listener.settimeout(0.1)
        self.port: int = self._listener.getsockname()[1]
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="hostile-peer", daemon=True)
        self._thread.start()

    def _read_item(self, conn: socket.socket) -> bytes | None:
        """Read up to one '>' (byte by byte: nothing after it is consumed)."""
        item = b""
        while not self._done.is_set():
            try:
                b = conn.recv(1)
            except TimeoutError:
                continue
            except OSError:
                return None
            if not b:
                return None
            self.received += b
            item += b
            if b == b">":
                return item
        return None

    def _serve(self) -> None:
        while not self._done.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with conn:
                conn.settimeout(0.1)
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.accepted.set()
                if self._play(conn):
                    self._vanish.wait()  # until vanish() or close()
                    if self._reset:  # close with RST instead of FIN
                        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER,
                                        struct.pack("ii", 1, 0))
                    return

    def _play(self, conn: socket.socket) -> bool:
        """The script on one connection; False if the peer left before '< open >'."""
        if self.hi is None:
            self._vanish.wait()
            return True
        conn.sendall(self.hi)
        if self._read_item(conn) is None:
            return False  # the port probe
        if self.open_reply is None:
            self._vanish.wait()
            return True
        conn.sendall(self.open_reply)
        if self._read_item(conn) is None or self.raw_reply is None:
            self._vanish.wait()
            return True
        conn.sendall(self.raw_reply)
        for chunk in self.chunks:
            conn.sendall(chunk)
        self.sent.set()
        return True

    def vanish(self, *, reset: bool = False) -> None:
        """Close the connection (FIN, or RST with ``reset``); the listener stays."""
        self._reset = reset
        self._vanish.set()
        self._thread.join(WAIT_S)

    def close(self) -> None:
        self._done.set()
        self._vanish.set()
        self._thread.join(WAIT_S)
        self._listener.close()

    def __enter__(self) -> HostilePeer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
