"""Quick baseline: wire codec cost and zenoh put → subscriber-callback latency on loopback.

Modes (all print one JSON object on stdout):

* ``micro``: msgpack encode / decode time per rate, state and health message (µs).
* ``inproc``: publisher and subscriber sessions in this process.
* ``multiproc`` (default): the subscriber runs in a child process (``--mode sub``);
  this process publishes and merges the child's JSON into its own.
* ``pub`` / ``sub``: the two halves, for running by hand in two terminals
  (``sub --listen tcp/127.0.0.1:7450`` first, then ``pub --connect ...``).

Latency = subscriber ``time.time()`` in the callback − the message's
``receive_time_s``, which the publisher stamps with ``time.time()`` just before
encoding and ``put`` (so it includes one encode, ~1 µs). The publisher paces
``--rate-hz`` messages per second by sleeping to absolute deadlines; messages of
the first ``--warmup-s`` seconds are excluded from the statistics. Receivers:
``bare`` (a zenoh callback that decodes the payload) or ``client``
(:class:`gyrotherm.client.Subscriber` with an ``on_rate`` callback).

Every session listens and connects on 127.0.0.1 only, with scouting off.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import socket
import subprocess
import sys
import threading
import time
import timeit
from typing import Any

import zenoh

from gyrotherm._zenoh import keys, open_session
from gyrotherm.client import Subscriber
from gyrotherm.codecs._wire import (
    HealthMessage,
    RateMessage,
    StateMessage,
    StatusFlags,
    decode_health,
    decode_rate,
    decode_state,
    encode_health,
    encode_rate,
    encode_state,
)

VEHICLE, SENSOR = "bench", "imu0"
END_KEY = "gyrotherm/bench/imu0/bench_end"


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _rate_msg(seq: int, stamp_s: float) -> RateMessage:
    return RateMessage(
        seq, seq * 0.0005, stamp_s, (0.0123, -0.0456, 0.789), (0.0223, -0.0356, 0.889),
        (0.01, 0.01, 0.1), StatusFlags.T_CLAMPED,
    )  # fmt: skip


def micro(n: int) -> dict[str, Any]:
    rate = _rate_msg(123_456, time.time())
    state = StateMessage(99, 12.5, time.time(), 31.2, 0.05, -1.2, 0.1, (0.01, 0.01, 0.1))
    drops = {"decode_error": 1, "counter_jump": 2}
    health = HealthMessage(7, 12.5, time.time(), 3600.0, 10**7, 10**7 - 3, drops,
                           StatusFlags.NONE, "cal-1")  # fmt: skip
    out: dict[str, Any] = {"iterations": n}
    for name, msg, enc, dec in (
        ("rate", rate, encode_rate, decode_rate),
        ("state", state, encode_state, decode_state),
        ("health", health, encode_health, decode_health),
    ):
        payload = enc(msg)
        best_enc = min(timeit.repeat(lambda: enc(msg), number=n, repeat=3)) / n  # noqa: B023
        best_dec = min(timeit.repeat(lambda: dec(payload), number=n, repeat=3)) / n  # noqa: B023
        out[name] = {"bytes": len(payload), "encode_us": round(best_enc * 1e6, 3),
                     "decode_us": round(best_dec * 1e6, 3)}  # fmt: skip
    build = min(timeit.repeat(lambda: encode_rate(_rate_msg(1, 2.0)), number=n, repeat=3)) / n
    out["rate"]["build_and_encode_us"] = round(build * 1e6, 3)
    return out


def _stats_us(lat_s: list[float]) -> dict[str, Any]:
    if not lat_s:
        return {"count": 0}
    s = sorted(lat_s)

    def pct(p: float) -> float:
        return round(s[max(1, math.ceil(p / 100 * len(s))) - 1] * 1e6, 1)

    return {"count": len(s), "mean_us": round(sum(s) / len(s) * 1e6, 1), "min_us": pct(0),
            "p50_us": pct(50), "p90_us": pct(90), "p99_us": pct(99),
            "max_us": pct(100)}  # fmt: skip


class Receiver:
    """Collects latencies (s) of rate messages after the warm-up, until the end marker."""

    def __init__(self, session: zenoh.Session, kind: str, warmup_n: int) -> None:
        self.latencies: list[float] = []
        self.received = 0
        self.sent: int | None = None
        self.done = threading.Event()
        self._cond = threading.Condition()
        self._warmup_n = warmup_n
        self._end = session.declare_subscriber(END_KEY, self._on_end)
        self._client: Subscriber | None = None
        if kind == "bare":
            self._sub = session.declare_subscriber(keys(VEHICLE, SENSOR).rate, self._on_bare)
        else:
            self._client = Subscriber(VEHICLE, SENSOR, session=session, on_rate=self._on_msg)

    def _on_bare(self, sample: zenoh.Sample) -> None:
        now = time.time()
        self._record(now, decode_rate(sample.payload.to_bytes()))

    def _on_msg(self, msg: RateMessage) -> None:
        self._record(time.time(), msg)

    def _record(self, now_s: float, msg: RateMessage) -> None:
        with self._cond:
            self.received += 1
            if msg.seq >= self._warmup_n:
                self.latencies.append(now_s - msg.receive_time_s)
            self._cond.notify_all()

    def wait_all(self, timeout_s: float) -> bool:
        """After the end marker: wait (bounded) for messages still in callback queues."""
        if not self.done.wait(timeout_s):
            return False
        with self._cond:
            return self._cond.wait_for(lambda: self.received >= (self.sent or 0), 5.0)

    def _on_end(self, sample: zenoh.Sample) -> None:
        self.sent = int(sample.payload.to_bytes())
        self.done.set()

    def result(self) -> dict[str, Any]:
        out = {"received": self.received, "sent": self.sent, "latency": _stats_us(self.latencies)}
        if self._client is not None:
            st = self._client.stats().rate
            out["client_gaps"], out["client_missing"] = st.gaps, st.missing
        return out


def publish(
    session: zenoh.Session, rate_hz: float, duration_s: float, *, express: bool
) -> dict[str, Any]:
    pub = session.declare_publisher(keys(VEHICLE, SENSOR).rate, express=express)
    matched = threading.Event()
    listener = pub.declare_matching_listener(lambda s: s.matching and matched.set())
    if pub.matching_status.matching:
        matched.set()
    if not matched.wait(30.0):
        raise SystemExit("no subscriber matched within 30 s")
    listener.undeclare()
    n = int(rate_hz * duration_s)
    period = 1.0 / rate_hz
    late = 0
    start = time.monotonic()
    for seq in range(n):
        deadline = start + seq * period
        delay = deadline - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        elif delay < -period:
            late += 1
        pub.put(encode_rate(_rate_msg(seq, time.time())))
    elapsed = time.monotonic() - start
    session.put(END_KEY, str(n).encode())
    return {"sent": n, "achieved_hz": round(n / elapsed, 1), "late_by_over_one_period": late}


def run_inproc(a: argparse.Namespace) -> dict[str, Any]:
    ep = _free_endpoint()
    with open_session(listen=[ep]) as pub_s, open_session(connect=[ep]) as sub_s:
        rx = Receiver(sub_s, a.receiver, int(a.rate_hz * a.warmup_s))
        pub = publish(pub_s, a.rate_hz, a.duration_s, express=a.express)
        rx.wait_all(30.0)
        return {"publisher": pub, "subscriber": rx.result()}


def run_sub(a: argparse.Namespace) -> dict[str, Any]:
    with open_session(listen=a.listen or [], connect=a.connect or []) as s:
        rx = Receiver(s, a.receiver, int(a.rate_hz * a.warmup_s))
        print("READY", flush=True)
        if not rx.wait_all(a.duration_s + 60.0) and not rx.done.is_set():
            return {"error": "no end marker", **rx.result()}
        return rx.result()


def run_pub(a: argparse.Namespace) -> dict[str, Any]:
    with open_session(listen=a.listen or [], connect=a.connect or []) as s:
        return {"publisher": publish(s, a.rate_hz, a.duration_s, express=a.express)}


def run_multiproc(a: argparse.Namespace) -> dict[str, Any]:
    ep = _free_endpoint()
    with open_session(listen=[ep]) as s:
        cmd = [sys.executable, os.path.abspath(__file__), "--mode", "sub", "--connect", ep,
               "--rate-hz", str(a.rate_hz), "--warmup-s", str(a.warmup_s),
               "--duration-s", str(a.duration_s), "--receiver", a.receiver]  # fmt: skip
        child = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
        try:
            assert child.stdout is not None
            if child.stdout.readline().strip() != "READY":
                raise SystemExit("subscriber process did not start")
            pub = publish(s, a.rate_hz, a.duration_s, express=a.express)
            out, _ = child.communicate(timeout=a.duration_s + 60.0)
        finally:
            if child.poll() is None:
                child.kill()
        return {"publisher": pub, "subscriber": json.loads(out)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="zenoh / wire-format baseline (JSON on stdout)")
    p.add_argument("--mode", choices=["micro", "inproc", "multiproc", "pub", "sub"],
                   default="multiproc")  # fmt: skip
    p.add_argument("--rate-hz", type=float, default=2000.0)
    p.add_argument("--duration-s", type=float, default=5.0)
    p.add_argument("--warmup-s", type=float, default=0.5)
    p.add_argument("--receiver", choices=["bare", "client"], default="bare")
    p.add_argument("--express", action="store_true", help="zenoh express (no batching)")
    p.add_argument("--listen", action="append", help="endpoint (pub/sub modes)")
    p.add_argument("--connect", action="append", help="endpoint (pub/sub modes)")
    p.add_argument("--iterations", type=int, default=100_000, help="micro mode")
    a = p.parse_args(argv)
    runners = {"micro": lambda: micro(a.iterations), "inproc": lambda: run_inproc(a),
               "multiproc": lambda: run_multiproc(a), "pub": lambda: run_pub(a),
               "sub": lambda: run_sub(a)}  # fmt: skip
    result = runners[a.mode]()
    if a.mode != "sub":
        result = {"mode": a.mode, "rate_hz": a.rate_hz, "duration_s": a.duration_s,
                  "receiver": a.receiver, "express": a.express, "python": platform.python_version(),
                  "cpus": os.cpu_count(), **result}  # fmt: skip
    print(json.dumps(result, indent=None if a.mode == "sub" else 2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
