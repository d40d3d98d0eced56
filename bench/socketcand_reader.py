"""socketcand reader speed: gyrotherm's SocketcandBus vs python-can's client, same run.

    .venv/bin/python bench/socketcand_reader.py [--frames 200000] [--repeats 5]

1. Records what the simulator's :class:`~gyrotherm.sim.SocketcandServer` writes
   for ``--frames`` :func:`~gyrotherm.sim._socketcand.demo_frame` frames (11- and
   29-bit ids, 0–8 data bytes): a raw TCP client does the handshake and keeps
   the bytes.
2. A replay server (a thread of this process; ``sendall`` of the recording
   releases the GIL) does the handshake with each client, waits until the client
   is constructed, then writes the recording at once.
3. Each reader — ``gyrotherm``: ``SocketcandBus.connect``; ``python-can``:
   ``can.Bus(interface="socketcand")`` — receives until it has every frame.
   Time = first ``recv`` call → last frame returned. Readers alternate
   (gyrotherm, python-can, gyrotherm, …) for ``--repeats`` rounds; the figure
   is the median frames/s, the ratio is gyrotherm / python-can of the medians.
   Also the reading thread's CPU time per frame (``time.thread_time``), steadier
   than the rate on a shared machine. Every frame's id and data is checked
   against the recording's source frames in the first round (a fast wrong
   reader would not count).

Prints one JSON object on stdout and a summary on stderr.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import socket
import statistics
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import can

from gyrotherm.bus import SocketcandBus
from gyrotherm.sim._socketcand import SocketcandServer, demo_frame

WAIT_S = 30.0


def _read_item(conn: socket.socket) -> bytes:
    item = b""
    while not item.endswith(b">"):
        b = conn.recv(1)
        if not b:
            raise ConnectionError(f"peer closed after {item!r}")
        item += b
    return item


def record(n: int) -> bytes:
    """The bytes the simulator's server writes for n demo frames after the handshake."""
    with SocketcandServer(client_queue_frames=n + 1) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=WAIT_S) as conn:
        assert _read_item(conn) == b"< hi >"
        conn.sendall(b"< open vcan0 >")
        assert _read_item(conn) == b"< ok >"
        conn.sendall(b"< rawmode >")
        assert _read_item(conn) == b"< ok >"
        assert server.wait_for_clients(1, WAIT_S)
        for i in range(n):
            server.send(demo_frame(i))
        chunks, items = [], 0
        while items < n:
            chunk = conn.recv(1 << 20)
            chunks.append(chunk)
            items += chunk.count(b">")
    return b"".join(chunks)


class Replay:
    """Handshake, then the recording, to each client; ``go`` releases the bytes."""

    def __init__(self, recording: bytes) -> None:
        self.recording = recording
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port: int = self.listener.getsockname()[1]
        self.go = threading.Event()

    def serve_one(self) -> threading.Thread:
        self.go.clear()
        thread = threading.Thread(target=self._serve, daemon=True)
        thread.start()
        return thread

    def _serve(self) -> None:
        conn, _ = self.listener.accept()
        with conn:
            conn.sendall(b"< hi >")
            _read_item(conn)
            conn.sendall(b"< ok >")
            _read_item(conn)
            conn.sendall(b"< ok >")
            if self.go.wait(WAIT_S):
                conn.sendall(self.recording)
                conn.recv(1)  # until the client closes


def time_reader(replay: Replay, n: int, open_reader: Callable[[int], Any],
                check: bool) -> tuple[float, float]:
    """(frames/s, CPU µs per frame of the reading thread) for one reader."""
    thread = replay.serve_one()
    reader = open_reader(replay.port)
    try:
        got: list[can.Message] = []
        recv = reader.recv
        replay.go.set()
        t0, cpu0 = time.perf_counter(), time.thread_time()
        while len(got) < n:
            msg = recv(WAIT_S)
            if msg is None:
                raise RuntimeError(f"{reader!r}: no frame for {WAIT_S} s after {len(got)}")
            if isinstance(msg, can.Message):
                got.append(msg)
        elapsed, cpu_s = time.perf_counter() - t0, time.thread_time() - cpu0
    finally:
        reader.shutdown()
        thread.join(WAIT_S)
    if check:
        for i, msg in enumerate(got):
            want = demo_frame(i)
            if (msg.arbitration_id, msg.is_extended_id, bytes(msg.data)) != (
                    want.arbitration_id, want.is_extended_id, bytes(want.data)):
                raise RuntimeError(f"{reader!r}: frame {i} is {msg}, expected {want}")
    return n / elapsed, cpu_s / n * 1e6


READERS: dict[str, Callable[[int], Any]] = {
    "gyrotherm": lambda port: SocketcandBus.connect("127.0.0.1", port, "vcan0"),
    "python-can": lambda port: can.Bus(interface="socketcand", host="127.0.0.1", port=port,
                                       channel="vcan0", ignore_config=True),
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=5)
    a = parser.parse_args(argv)
    logging.getLogger("can").setLevel(logging.ERROR)  # python-can's per-read warnings
    recording = record(a.frames)
    replay = Replay(recording)
    rates: dict[str, list[float]] = {name: [] for name in READERS}
    cpu_us: dict[str, list[float]] = {name: [] for name in READERS}
    for r in range(a.repeats):
        for name, open_reader in READERS.items():
            rate, cpu = time_reader(replay, a.frames, open_reader, check=r == 0)
            rates[name].append(rate)
            cpu_us[name].append(cpu)
    replay.listener.close()
    medians = {name: statistics.median(v) for name, v in rates.items()}
    cpu_medians = {name: statistics.median(v) for name, v in cpu_us.items()}
    result = {
        "frames": a.frames,
        "bytes": len(recording),
        "repeats": a.repeats,
        "frames_per_s": {name: [round(x) for x in v] for name, v in rates.items()},
        "median_frames_per_s": {name: round(m) for name, m in medians.items()},
        "ratio_gyrotherm_over_python_can": round(medians["gyrotherm"] / medians["python-can"],
                                                 2),
        "median_cpu_us_per_frame": {name: round(m, 2) for name, m in cpu_medians.items()},
        "loadavg_1_5_15": list(os.getloadavg()),
    }
    print(json.dumps(result))
    print(f"socketcand reader, {a.frames} frames ({len(recording)} bytes), median of "
          f"{a.repeats}: gyrotherm {medians['gyrotherm']:,.0f} frames/s, python-can "
          f"{medians['python-can']:,.0f} frames/s, ratio "
          f"{result['ratio_gyrotherm_over_python_can']}; reading thread CPU "
          f"{cpu_medians['gyrotherm']:.2f} vs {cpu_medians['python-can']:.2f} µs/frame",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
