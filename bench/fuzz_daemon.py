"""Long fuzz: ≥ 10⁶ socketcand items, malformed ones included, into a real ``gyrotherm run``.

A hostile socketcand server (this process, 127.0.0.1) completes the handshake
and then streams a seeded mix of items to the daemon (a ``python -m gyrotherm
run`` subprocess), in random TCP write sizes so items are split across reads:

==================  ==================================================  ==================
category            what is sent                                        counted by the
                                                                        daemon as
==================  ==================================================  ==================
rate                valid rate frames of a 1 kHz gyro                   published (rate)
temperature         valid temperature frames (10 Hz sensor time)        published (state)
crc                 a copy of a valid frame with one data digit changed  crc_mismatch
unknown_id          a valid frame on an id the DBC does not map          unknown_id
bad_id              ``< frame ZZZ … >``                                  transport_malformed
bad_time            a time stamp that is not a number                    transport_malformed
bad_hex             data with a non-hex digit                            transport_malformed
odd_hex             data with an odd number of hex digits                transport_malformed
non_ascii           bytes ≥ 0x80 inside an item                          transport_malformed
nul                 a NUL byte inside an item                            transport_malformed
oversize            one 5000-byte item                                   transport_malformed
server_error        ``< error unknown command >``                        transport_error
other               ``< ok >`` after the handshake                       transport_other
==================  ==================================================  ==================

A gyrotherm ``Subscriber`` in this process receives the rate and state
messages, so "published" means delivered. Checked at the end (exact, from the
daemon's summary line after SIGTERM): frames in == items sent, published +
Σ drops == frames in, every category counted under its reason, subscriber
received == published. Also: the daemon's stderr line count (logging must be
rate-limited), its exit status, peak RSS (VmHWM), CPU time and wall time.

Prints one JSON object on stdout, a summary on stderr. Nothing asserts: a
mismatch shows as ``"exact": false`` with both sides.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, Run

VEHICLE, SENSOR = "fuzz", "imu0"
SENSOR_RATE_HZ = 1000.0
EXPECTED = {
    "crc": "crc_mismatch",
    "unknown_id": "unknown_id",
    "bad_id": "transport_malformed",
    "bad_time": "transport_malformed",
    "bad_hex": "transport_malformed",
    "odd_hex": "transport_malformed",
    "non_ascii": "transport_malformed",
    "nul": "transport_malformed",
    "oversize": "transport_malformed",
    "server_error": "transport_error",
    "other": "transport_other",
}
#: Share of inserted bad items per category (relative weights).
WEIGHTS = {"crc": 6, "unknown_id": 3, "bad_id": 2, "bad_time": 2, "bad_hex": 2, "odd_hex": 2,
           "non_ascii": 2, "nul": 1, "oversize": 0.05, "server_error": 2, "other": 1}


def log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def valid_lines(n_rate: int, seed: int) -> tuple[list[bytes], list[bool]]:
    """socketcand lines of a synthetic gyro, and whether each is a rate frame."""
    from gyrotherm.sim import frames_from_run
    from gyrotherm.sim._socketcand_wire import encode_frame

    rng = np.random.default_rng(seed)
    t = np.arange(n_rate) / SENSOR_RATE_HZ
    temp = 20.0 + 25.0 * t / max(float(t[-1]), 1e-9)
    rates = {a: 0.05 * (i + 1) + 0.01 * rng.standard_normal(n_rate) for i, a in enumerate("xyz")}
    run = Run("fuzz", t, temp, rates, metadata={"temperature_period_s": "0.1"})
    encoder = FrameEncoder()
    rate_id = encoder.layout.rate.frame_id
    lines, is_rate = [], []
    for f in frames_from_run(run, encoder=encoder, t0_s=1_700_000_000.0):
        lines.append(encode_frame(f))
        is_rate.append(f.arbitration_id == rate_id)
    return lines, is_rate


def bad_item(kind: str, model: bytes, rnd: random.Random) -> bytes:
    """One malformed or unwanted item; ``model`` is a valid frame line to mutate."""
    _, _, ident, stamp, data, _ = model.split(b" ")
    if kind == "crc":  # change one data digit (CRC-8 catches every single-digit change)
        i = rnd.randrange(len(data))
        digit = b"0123456789ABCDEF".replace(data[i:i + 1], b"")[rnd.randrange(15)]
        data = data[:i] + bytes([digit]) + data[i + 1:]
        return b"< frame " + ident + b" " + stamp + b" " + data + b" >"
    if kind == "unknown_id":
        return b"< frame 7FF " + stamp + b" " + data + b" >"
    if kind == "bad_id":
        return b"< frame ZZZ " + stamp + b" " + data + b" >"
    if kind == "bad_time":
        return b"< frame " + ident + b" 17x0.00abc " + data + b" >"
    if kind == "bad_hex":
        return b"< frame " + ident + b" " + stamp + b" " + data[:-1] + b"G >"
    if kind == "odd_hex":
        return b"< frame " + ident + b" " + stamp + b" " + data[:-1] + b" >"
    if kind == "non_ascii":
        return b"< frame " + ident + b" " + stamp + b" " + data[:4] + b"\xc3\xa9\xff >"
    if kind == "nul":
        return b"< frame " + ident + b"\x00 " + stamp + b" " + data + b" >"
    if kind == "oversize":
        return b"< frame " + b"A" * 5000 + b" >"
    if kind == "server_error":
        return b"< error unknown command >"
    if kind == "other":
        return b"< ok >"
    raise ValueError(kind)


class HostileServer:
    """One-client socketcand server: handshake, then the prepared byte stream."""

    def __init__(self, payload: list[bytes], seed: int) -> None:
        self._sock = socket.create_server(("127.0.0.1", 0))
        self.port = int(self._sock.getsockname()[1])
        self._payload = payload
        self._rnd = random.Random(seed)
        self.done = threading.Event()
        self.go = threading.Event()
        """Set by the caller once its subscriber is live: only then the stream starts."""
        self.error: str | None = None
        self.sent_bytes = 0
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _expect(self, conn: socket.socket, word: bytes) -> None:
        buf = b""
        while b">" not in buf:
            chunk = conn.recv(4096)
            if not chunk:
                raise ConnectionError(f"peer closed before {word!r}")
            buf += chunk
        if word not in buf:
            raise ConnectionError(f"expected {word!r}, got {buf!r}")

    def _handshake(self) -> socket.socket:
        """Accept until a peer completes the handshake (the daemon probes the port
        with a bare connect first)."""
        while True:
            conn, _ = self._sock.accept()
            try:
                conn.settimeout(60.0)
                conn.sendall(b"< hi >")
                self._expect(conn, b"open")
                conn.sendall(b"< ok >")
                self._expect(conn, b"rawmode")
                conn.sendall(b"< ok >")
                return conn
            except OSError:
                conn.close()

    def _serve(self) -> None:
        try:
            conn = self._handshake()
            with conn:
                self.go.wait(120.0)
                blob = b"".join(self._payload)
                i = 0
                while i < len(blob):  # random write sizes: items split across reads
                    n = self._rnd.choice((1, 7, 64, 1000, 4096, 65536))
                    conn.sendall(blob[i:i + n])
                    i += n
                self.sent_bytes = len(blob)
                self.done.set()
                # keep the link open until the daemon is stopped (EOF is not the test)
                conn.settimeout(None)
                while conn.recv(4096):
                    pass
        except OSError as exc:
            self.error = repr(exc)
            self.done.set()

    def close(self) -> None:
        self._sock.close()


def build_stream(n_items: int, bad_share: float, seed: int) -> tuple[list[bytes], Counter[str]]:
    rnd = random.Random(seed)
    n_valid = int(n_items * (1.0 - bad_share))
    lines, is_rate = valid_lines(int(n_valid * 0.99) + 1, seed)
    kinds, weights = zip(*WEIGHTS.items(), strict=True)
    out: list[bytes] = []
    sent: Counter[str] = Counter()
    p_bad = bad_share / (1.0 - bad_share)
    for line, rate in zip(lines, is_rate, strict=True):
        if rnd.random() < p_bad:
            kind = rnd.choices(kinds, weights)[0]
            out.append(bad_item(kind, line, rnd))
            sent[kind] += 1
        out.append(line)
        sent["rate" if rate else "temperature"] += 1
    return out, sent


def proc_stat(pid: int) -> dict[str, float]:
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    cpu = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    out = {"cpu_s": cpu}
    with open(f"/proc/{pid}/status", encoding="ascii") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                out[f"{key}_MB"] = int(value.split()[0]) / 1024
    return out


def run(a: argparse.Namespace) -> dict[str, Any]:
    t_build = time.monotonic()
    stream, sent = build_stream(a.items, a.bad_share, a.seed)
    log(f"built {len(stream)} items in {time.monotonic() - t_build:.1f} s: {dict(sent)}")
    server = HostileServer(stream, a.seed + 1)
    zport = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "fuzz.toml"
        cfg.write_text(
            f'vehicle = "{VEHICLE}"\nsensor = "{SENSOR}"\nhealth_period_s = 0.2\n\n'
            f'[can]\ninterface = "socketcand"\nhost = "127.0.0.1"\nport = {server.port}\n'
            f'channel = "vcan0"\nreopen_after_s = 3600\n\n'
            f'[zenoh]\nmode = "peer"\nlisten = ["tcp/127.0.0.1:{zport}"]\n', encoding="utf-8")
        errlog = Path(tmp) / "stderr.log"
        latest: dict[str, Any] = {}

        def ignore(_msg: Any) -> None:
            return None

        with Subscriber(VEHICLE, SENSOR, connect=[f"tcp/127.0.0.1:{zport}"],
                        on_rate=ignore, on_state=ignore,
                        on_health=lambda h: latest.__setitem__("health", h)
                        ) as sub, open(errlog, "w+b") as err:
            # the subscriber connects with zenoh's retry; the daemon listens when up
            t0 = time.monotonic()
            daemon = subprocess.Popen([sys.executable, "-m", "gyrotherm", "run", "--config",
                                       str(cfg)], stdout=subprocess.PIPE, stderr=err)
            total = len(stream)
            ok = sub.wait_for(lambda s: s.health.received > 0, timeout_s=60.0)
            server.go.set()
            done = server.done.wait(a.timeout_s)
            # every item counted: the daemon's health says frames_received == total
            caught = sub.wait_for(
                lambda _s: "health" in latest and latest["health"].frames_received >= total,
                timeout_s=a.timeout_s)
            elapsed = time.monotonic() - t0
            usage = proc_stat(daemon.pid)
            stats = sub.stats()
            daemon.send_signal(signal.SIGTERM)
            t_term = time.monotonic()
            try:
                out, _ = daemon.communicate(timeout=a.stop_timeout_s)
                stop_s: float | None = time.monotonic() - t_term
            except subprocess.TimeoutExpired:  # SIGTERM ignored: what systemd would SIGKILL
                daemon.kill()
                out, _ = daemon.communicate()
                stop_s = None
            code = daemon.returncode
            err.seek(0)
            stderr_lines = err.read().decode("utf-8", "replace").splitlines()
    server.close()
    summary = out.decode("utf-8", "replace").strip().splitlines()[-1] if out else ""
    m = re.match(r"frames in (\d+), published (\d+), dropped (\d+) (\{.*\})", summary)
    drops: dict[str, int] = json.loads(m[4].replace("'", '"')) if m else {}
    frames_in = int(m[1]) if m else -1
    published = int(m[2]) if m else -1
    expected_drops: Counter[str] = Counter()
    for kind, reason in EXPECTED.items():
        expected_drops[reason] += sent[kind]
    valid = sent["rate"] + sent["temperature"]
    checks = {
        "every_item_counted": frames_in == total,
        "published_plus_dropped": published + sum(drops.values()) == frames_in,
        "valid_frames_published": published == valid,
        "drops_by_reason": dict(expected_drops) == {k: v for k, v in drops.items() if v},
        "subscriber_received_all": (stats.rate.received + stats.state.received) == published
        and stats.rate.gaps == 0,
        "exit_status_0": code == 0,
        "sigterm_honoured": stop_s is not None,
    }
    return {
        "benchmark": "fuzz_daemon",
        "command": " ".join(["bench/fuzz_daemon.py", *sys.argv[1:]]),
        "items": total,
        "bytes": server.sent_bytes,
        "sent_by_category": dict(sent),
        "expected_drops": dict(expected_drops),
        "daemon": {"frames_in": frames_in, "published": published, "drops": drops,
                   "exit_status": code, "stderr_lines": len(stderr_lines),
                   "stderr_tail": stderr_lines[-5:], **usage},
        "subscriber": {"rate": stats.rate.received, "state": stats.state.received,
                       "rate_gaps": stats.rate.gaps},
        "wall_s": elapsed,
        "stop_after_sigterm_s": stop_s,
        "items_per_s": total / elapsed if elapsed > 0 else None,
        "health_seen": ok, "server_done": done, "caught_up": caught,
        "server_error": server.error,
        "checks": checks,
        "exact": all(checks.values()),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--items", type=int, default=1_000_000, help="items to send (1000000)")
    p.add_argument("--bad-share", type=float, default=0.25,
                   help="share of inserted bad items (0.25)")
    p.add_argument("--seed", type=int, default=1, help="random seed (1)")
    p.add_argument("--stop-timeout-s", type=float, default=15.0,
                   help="SIGTERM → exit bound before SIGKILL, s (15, TimeoutStopSec)")
    p.add_argument("--timeout-s", type=float, default=300.0,
                   help="longest wait for the daemon to count every item, s (300)")
    a = p.parse_args(argv)
    result = run(a)
    print(json.dumps(result, indent=2))
    d = result["daemon"]
    log(f"{result['items']} items in {result['wall_s']:.1f} s "
        f"({result['items_per_s']:.0f}/s): daemon in {d['frames_in']}, published "
        f"{d['published']}, drops {d['drops']}; stderr {d['stderr_lines']} lines; "
        f"VmHWM {d.get('VmHWM_MB', 0):.0f} MB; exact {result['exact']} {result['checks']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
