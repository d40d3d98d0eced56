"""Streaming throughput: rate frames/s through decode → estimate → compensate → publish.

Every rate frame must reach a subscriber in **another process** (zero loss: rate
messages received == rate frames sent, no ``seq`` gap, daemon drops 0). Three
chains, measured interleaved in one run (round-robin, ``--trials`` rounds):

* ``bare``: a bare zenoh publisher process (no daemon) → the subscriber process:
  pre-built 108-byte rate payloads (stamped and encoded per message), congestion
  control BLOCK. The transport + subscriber ceiling, the same-run baseline.
* ``core``: the daemon's processing core in a child process,
  ``Daemon(parse_config(...)).run(source=ScheduledSource)``: pre-built
  ``can.Message`` objects handed out by an in-process frame source → decode →
  T/ΔT Kalman (per temperature frame) → compensation → msgpack → zenoh put.
* ``full``: the whole cross-process chain: frames played by this process onto a
  :class:`~gyrotherm.sim.SocketcandServer` on 127.0.0.1 → the daemon as a process
  (``python -m gyrotherm run --config FILE``, gyrotherm's socketcand client) →
  the subscriber process.

The subscriber is :class:`gyrotherm.client.Subscriber` (decode, seq and latency
accounting) with an ``on_rate`` callback that records arrival times. Frames come
from a synthetic 1 kHz gyro (3 axes, temperature frames at 10 Hz sensor time, a
fitted calibration loaded), so ~1 % of the frames are temperature frames.

Two modes per chain:

* ``unpaced``: as fast as the chain takes them, with back-pressure (zenoh BLOCK
  towards the subscriber; for ``full`` the player flushes the socketcand queue
  every 4096 frames). Throughput = rate frames / (last subscriber callback −
  first send). Loss must be 0 whatever the speed: this is the zero-loss ceiling.
* ``paced``: frames scheduled at ``--rate`` rate frames/s (absolute schedule,
  batches when behind), as a bus that does not wait. For ``full`` the socketcand
  server never blocks (a frame is dropped when its 65 536-frame queue is full).
  The frame's sensor time is its scheduled wall-clock send time, so the
  subscriber measures *lag* = callback time − schedule. The chain **keeps up**
  when there is zero loss and p99 lag < ``--max-lag-ms`` (default 50 ms).

Also: ``latency`` = callback − ``receive_time_s`` (the daemon's arrival stamp),
CPU per process (utime+stime from /proc over the trial / wall time, 100 % = one
core), the daemon processes' VmRSS/VmHWM after the trials, the daemon config
congestion control of the daemon's live rate publisher (read in the ``core``
child; the daemon always uses BLOCK), and a check of what BLOCK buys: one more
unpaced ``core`` daemon feeding a deliberately slow subscriber (it busy-waits
``--slow-us`` µs per message) must lose nothing (the daemon slows down to the
subscriber), while the negative control, the bare publisher with congestion
control DROP into the same slow subscriber, should lose messages: this shows that
the loss checks detect loss.

Daemon settings for the bench: ``health_period_s = 0.1`` (the daemon's counters
are read from its health messages, which must be fresh after each trial) and,
for ``full``, ``reopen_after_s = 3600`` (the bench idles between trials longer
than the 5 s after which the daemon would reconnect to a silent bus).

Prints one JSON object on stdout, a human summary on stderr. Everything listens
on 127.0.0.1 only; zenoh sessions come from :func:`gyrotherm._zenoh.session_config`
(no scouting). Internal roles (``--role sub|core|bare``) are the child processes.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import queue
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from array import array
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any

import can
import numpy as np

from gyrotherm._zenoh import keys, open_session
from gyrotherm.bus import FrameSource
from gyrotherm.client import Subscriber
from gyrotherm.codecs import (
    FrameDecoder,
    FrameEncoder,
    HealthMessage,
    RateMessage,
    Run,
    StateMessage,
    encode_rate,
)

VEHICLE = "bench"
SENSOR = "imu0"
BARE_SENSOR = "bare0"
SENSOR_RATE_HZ = 1000.0  # synthetic gyro sample rate (sensor time)
TEMPERATURE_PERIOD_S = 0.1  # sensor time
CAN_1MBIT_FRAMES_S = 1e6 / 111  # saturated classic CAN, 8-byte std frames, no stuffing
_STUFFED_FRAME_BITS = 135  # worst-case bit stuffing

JSONDict = dict[str, Any]


# --- shared helpers (stream_latency.py imports these) ------------------------------------


def log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def source_version() -> JSONDict:
    """The git commit of this tree and the files under src/ that differ from it (read-only)."""
    repo = Path(__file__).resolve().parent.parent

    def git(*args: str) -> str:
        try:
            done = subprocess.run(["git", "-C", str(repo), *args], capture_output=True,
                                  text=True, timeout=10)  # fmt: skip
        except (OSError, subprocess.TimeoutExpired):
            return ""
        return done.stdout.rstrip() if done.returncode == 0 else ""

    dirty = [line[3:] for line in git("status", "--porcelain", "--", "src").splitlines()]
    return {"commit": git("rev-parse", "--short", "HEAD") or None, "modified_src": dirty}


def machine() -> JSONDict:
    load = os.getloadavg()
    return {"python": platform.python_version(), "cpus": os.cpu_count(),
            "nproc": len(os.sched_getaffinity(0)), "platform": platform.platform(),
            "loadavg_1_5_15": [round(x, 2) for x in load], "source": source_version()}  # fmt: skip


def synthetic_run(n_rate: int, *, seed: int = 1) -> Run:
    """A 3-axis gyro at ``SENSOR_RATE_HZ``: small biased noise, temperature 20 → 45 °C."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_rate) / SENSOR_RATE_HZ
    temp = 20.0 + 25.0 * t / max(t[-1], 1e-9)
    rates = {a: 0.05 * (i + 1) + 0.01 * rng.standard_normal(n_rate)
             for i, a in enumerate("xyz")}  # fmt: skip
    return Run("bench-synthetic", t, temp, rates,
               metadata={"temperature_period_s": str(TEMPERATURE_PERIOD_S)})  # fmt: skip


def build_frames(n_rate: int) -> tuple[list[can.Message], list[float]]:
    """Pre-built frames (rate + temperature) and their sensor times relative to the first."""
    from gyrotherm.sim import frames_from_run

    frames = list(frames_from_run(synthetic_run(n_rate), encoder=FrameEncoder()))
    t0 = frames[0].timestamp
    return frames, [f.timestamp - t0 for f in frames]


UNPACED_INV_SPEED = 1e-3
"""Unpaced trials stamp their frames 1000× compressed (150 000 frames at 1 kHz span
0.15 s of sensor time, not 150 s): every trial then starts after the previous one's
last stamp, as a real sensor's time would, instead of jumping back to the wall clock
after an unpaced trial ran 150 s into the future (the daemon rightly takes such a
jump as a time base change and drops 4 frames per stream)."""


def restamp(frames: Sequence[can.Message], rel_s: Sequence[float], start_s: float,
            inv_speed: float) -> None:
    """Timestamps := ``start_s + rel·inv_speed`` (the wall-clock schedule when paced)."""
    for f, r in zip(frames, rel_s, strict=False):
        f.timestamp = start_s + r * inv_speed


@functools.cache
def _frame_keys() -> tuple[tuple[int, bool], tuple[int, bool]]:
    """(id, extended?) of the rate and of the temperature message in the shipped DBC."""
    layout = FrameDecoder().layout
    return ((layout.rate.frame_id, layout.rate.is_extended_id),
            (layout.temperature.frame_id, layout.temperature.is_extended_id))  # fmt: skip


def _is_rate(f: can.Message) -> bool:
    return (f.arbitration_id, f.is_extended_id) == _frame_keys()[0]


def count_kinds(frames: Sequence[can.Message]) -> tuple[int, int]:
    """(rate frames, temperature frames) by the shipped DBC's ids."""
    rate, temp = _frame_keys()
    keys_ = [(f.arbitration_id, f.is_extended_id) for f in frames]
    return keys_.count(rate), keys_.count(temp)


def prefix_for(frames: Sequence[can.Message], n_rate: int) -> int:
    """Length of the shortest prefix of ``frames`` holding ``n_rate`` rate frames (or all)."""
    seen = 0
    for i, f in enumerate(frames):
        seen += _is_rate(f)
        if seen >= n_rate:
            return i + 1
    return len(frames)


def fit_calibration(directory: Path) -> Path:
    """Fit the paper model on three short simulated chamber runs; save it; return the path."""
    from gyrotherm.compensation import features, fit
    from gyrotherm.estimators import EstimatorConfig
    from gyrotherm.sim import GyroParams, chamber_runs

    runs = chamber_runs([5, 20, 60], seed=8, rate_hz=1.0, hold_s=1200)
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    cal = fit([features(r, est) for r in runs], "paper", estimator=est)
    return cal.save(directory / "bench.calibration.json")


def pct_ms(values: np.ndarray, pcts: Sequence[float] = (50, 99)) -> JSONDict:
    """Nearest-rank percentiles (as gyrotherm.client.percentile) and max, in ms."""
    if len(values) == 0:
        return {"count": 0}
    s = np.sort(values)
    n = len(s)
    out: JSONDict = {"count": int(n)}
    for p in pcts:
        out[f"p{p:g}_ms"] = round(float(s[max(1, math.ceil(p / 100 * n)) - 1]) * 1e3, 3)
    out["max_ms"] = round(float(s[-1]) * 1e3, 3)
    return out


def median(values: Sequence[float]) -> float | None:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return round(float(np.median(vals)), 3) if vals else None


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process (all threads), s."""
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def thread_cpu_seconds(pid: int) -> dict[str, float]:
    """utime + stime per thread name (threads of one name summed), s; {} once gone."""
    out: dict[str, float] = {}
    tick = os.sysconf("SC_CLK_TCK")
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/stat", encoding="ascii", errors="replace") as f:
                text = f.read()
        except OSError:
            continue
        name = text[text.index("(") + 1 : text.rindex(")")]
        fields = text.rsplit(")", 1)[1].split()
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return out


def system_busy_seconds() -> tuple[float, float]:
    """(busy, total) CPU seconds of the whole machine since boot, from /proc/stat."""
    with open("/proc/stat", encoding="ascii") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    tick = os.sysconf("SC_CLK_TCK")
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)
    return (sum(fields) - idle) / tick, sum(fields) / tick


def memory_kb(pid: int) -> JSONDict:
    out: JSONDict = {}
    with open(f"/proc/{pid}/status", encoding="ascii") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                out[f"{key}_kB"] = int(value.split()[0])
    return out


class LineChild:
    """A child process speaking a line protocol on stdin/stdout (stderr inherited)."""

    def __init__(self, name: str, argv: list[str]) -> None:
        self.name = name
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, bufsize=1)  # fmt: skip
        self._lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def expect(self, prefix: str, timeout_s: float) -> str:
        """The payload of the next line starting with ``prefix`` (other lines are logged)."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                line = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise TimeoutError(f"{self.name}: no {prefix!r} within {timeout_s} s") from None
            if line is None:
                raise RuntimeError(f"{self.name}: exited ({self.proc.wait()}) before {prefix!r}")
            if line.startswith(prefix):
                return line[len(prefix) :].strip()
            log(f"[{self.name}] {line}")

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def ask(self, line: str, prefix: str, timeout_s: float) -> str:
        self.send(line)
        return self.expect(prefix, timeout_s)

    def close(self, timeout_s: float = 15.0) -> None:
        if self.proc.poll() is None:
            try:
                self.send("QUIT")
                self.proc.wait(timeout_s)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()


def script_argv(role: str, *args: str) -> list[str]:
    return [sys.executable, os.path.abspath(__file__), "--role", role, *args]


# --- child role: subscriber ----------------------------------------------------------


class _Recorder:
    """Arrival records of one trial, filled from zenoh's callback thread."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.reached = threading.Event()
        self.target = math.inf
        self.cb = array("d")
        self.sensor = array("d")
        self.receive = array("d")
        self.states = 0
        self.health_cond = threading.Condition()
        self.health: HealthMessage | None = None

    def on_health(self, msg: HealthMessage) -> None:
        with self.health_cond:
            self.health = msg
            self.health_cond.notify_all()

    def fresh_health(self, after_s: float, timeout_s: float = 10.0) -> HealthMessage | None:
        """The first health message the daemon made after wall-clock ``after_s``."""
        with self.health_cond:
            self.health_cond.wait_for(
                lambda: self.health is not None and self.health.receive_time_s > after_s,
                timeout_s)
            return self.health

    def reset(self, target: float) -> None:
        with self.lock:
            self.cb, self.sensor, self.receive = array("d"), array("d"), array("d")
            self.states = 0
            self.target = target
            self.reached.clear()

    def on_rate(self, msg: RateMessage) -> None:
        now = time.time()
        with self.lock:
            self.cb.append(now)
            self.sensor.append(msg.sensor_time_s)
            self.receive.append(msg.receive_time_s)
            if len(self.cb) >= self.target:
                self.reached.set()

    def slow(self, busy_s: float) -> Callable[[RateMessage], None]:
        """``on_rate`` that then busy-waits ``busy_s`` seconds (a slow consumer)."""

        def on_rate(msg: RateMessage) -> None:
            self.on_rate(msg)
            end = time.perf_counter() + busy_s
            while time.perf_counter() < end:
                pass

        return on_rate

    def on_state(self, msg: StateMessage) -> None:
        with self.lock:
            self.states += 1


def role_sub(a: argparse.Namespace) -> int:
    """``READY`` once matched; ``MARK`` → ``OK``;
    ``WAIT n_rate n_state timeout_s idle_s [skip]`` → ``RESULT {json}``; ``QUIT``."""
    rec = _Recorder()
    on_rate = rec.slow(a.slow_us * 1e-6) if a.slow_us > 0 else rec.on_rate
    sub = Subscriber(VEHICLE, a.sensor, connect=[a.connect], on_rate=on_rate,
                     on_state=rec.on_state, on_health=rec.on_health,
                     reservoir_size=64)  # fmt: skip
    with sub:
        if a.health and rec.fresh_health(0.0, 30.0) is None:
            print("ERROR no health message from the daemon within 30 s", flush=True)
            return 1
        print("READY", flush=True)
        base_stats = sub.stats()
        base_health = None
        for line in sys.stdin:
            cmd = line.split()
            if not cmd or cmd[0] == "QUIT":
                break
            if cmd[0] == "MARK":
                base_health = rec.fresh_health(time.time()) if a.health else None
                base_stats = sub.stats()
                rec.reset(math.inf)
                print("OK", flush=True)
            elif cmd[0] == "WAIT":
                n_rate, n_state = int(cmd[1]), int(cmd[2])
                timeout_s, idle_s = float(cmd[3]), float(cmd[4])
                skip = int(cmd[5]) if len(cmd) > 5 else 0
                with rec.lock:
                    rec.target = n_rate
                    if len(rec.cb) >= n_rate:
                        rec.reached.set()
                deadline = time.monotonic() + timeout_s
                last_n, last_change = -1, time.monotonic()
                while not rec.reached.wait(0.1):
                    now = time.monotonic()
                    if len(rec.cb) != last_n:
                        last_n, last_change = len(rec.cb), now
                    if now >= deadline or now - last_change >= idle_s:
                        break
                health = rec.fresh_health(time.time()) if a.health else None
                result = _sub_result(rec, base_stats, sub.stats(), base_health, health,
                                     n_rate, n_state, skip)  # fmt: skip
                print("RESULT " + json.dumps(result), flush=True)
    return 0


def _sub_result(rec: _Recorder, s0: Any, s1: Any, h0: HealthMessage | None,
                h1: HealthMessage | None, n_rate: int, n_state: int, skip: int) -> JSONDict:
    """Counts, and latency/lag percentiles over the rate messages after the first ``skip``."""
    with rec.lock:
        cb = np.frombuffer(rec.cb, dtype=float).copy()
        sensor = np.frombuffer(rec.sensor, dtype=float).copy()
        receive = np.frombuffer(rec.receive, dtype=float).copy()
        states = rec.states
    out: JSONDict = {
        "expected_rate": n_rate, "expected_state": n_state,
        "received_rate": len(cb), "received_state": states,
        "gaps": s1.rate.gaps - s0.rate.gaps, "missing": s1.rate.missing - s0.rate.missing,
        "state_gaps": s1.state.gaps - s0.state.gaps,
        "first_cb_s": float(cb[0]) if len(cb) else None,
        "last_cb_s": float(cb[-1]) if len(cb) else None,
        "skipped": min(skip, len(cb)),
        "latency": pct_ms((cb - receive)[skip:]),
        "lag": pct_ms((cb - sensor)[skip:]),
    }  # fmt: skip
    if h0 is not None and h1 is not None:
        drops = {k: v - h0.drops.get(k, 0) for k, v in h1.drops.items() if v - h0.drops.get(k, 0)}
        out["daemon"] = {"frames_received": h1.frames_received - h0.frames_received,
                         "frames_published": h1.frames_published - h0.frames_published,
                         "drops": drops}  # fmt: skip
    return out


# --- child role: daemon core with an in-process scheduled source -----------------------


class ScheduledSource(FrameSource):
    """Pre-built frames handed to the daemon on an absolute schedule.

    :meth:`play` restamps the first ``n`` frames with their wall-clock due time
    (``start + rel·inv_speed``; unpaced: :data:`UNPACED_INV_SPEED`, all due at once) and
    arms a trial; :meth:`recv` returns a frame once it is due (sleeping at most
    ``timeout_s``), so a slow consumer gets frames in batches, never fewer. After
    the last frame it calls ``on_done`` with the trial's figures.
    """

    def __init__(self, frames: list[can.Message], rel_s: list[float],
                 on_done: Callable[[JSONDict], None]) -> None:
        self._frames, self._rel, self._on_done = frames, rel_s, on_done
        self._cond = threading.Condition()
        self._active = False
        self._paced = False
        self._i = self._n = 0
        self._t_start = 0.0
        self._closed = False

    @property
    def is_shutdown(self) -> bool:
        return self._closed

    def shutdown(self) -> None:
        self._closed = True

    def play(self, n: int, inv_speed: float) -> None:
        n = min(n, len(self._frames))
        start = time.time() + 0.05 + 0.4e-6 * n
        restamp(self._frames[:n], self._rel[:n], start, inv_speed or UNPACED_INV_SPEED)
        time.sleep(max(0.0, start - time.time()))
        with self._cond:
            self._i, self._n, self._paced = 0, n, inv_speed > 0
            self._t_start = time.time()
            self._active = True
            self._cond.notify_all()

    def recv(self, timeout_s: float | None = None) -> can.Message | None:
        if not self._active:
            with self._cond:
                self._cond.wait_for(lambda: self._active, timeout_s)
                if not self._active:
                    return None
        i = self._i
        if i >= self._n:
            self._finish()
            return None
        msg: can.Message = self._frames[i]
        if self._paced:
            wait = msg.timestamp - time.time()
            if wait > 0:
                if timeout_s is not None and wait > timeout_s:
                    time.sleep(timeout_s)
                    return None
                time.sleep(wait)
        self._i = i + 1
        return msg

    def _finish(self) -> None:
        now = time.time()
        last_due = self._frames[self._n - 1].timestamp if self._paced else math.nan
        self._active = False
        self._on_done({"frames": self._n, "t_start_s": self._t_start, "t_end_s": now,
                       "final_lag_ms": round((now - last_due) * 1e3, 3) if self._paced else None})


def _core_config(a: argparse.Namespace) -> Any:
    from gyrotherm.daemon import parse_config

    return parse_config({
        "vehicle": VEHICLE, "sensor": SENSOR, "calibration": a.calibration,
        "health_period_s": 0.1,
        "can": {"interface": "virtual", "channel": "bench", "recv_timeout_s": 0.1},
        "zenoh": {"listen": [a.listen]},
    })  # fmt: skip


def _cc_name(cc: object) -> str | None:
    return None if cc is None else str(cc).rsplit(".", 1)[-1].upper()


def role_core(a: argparse.Namespace) -> int:
    """``READY`` when up; ``PLAY n inv_speed`` → ``DONE {json}``; ``QUIT`` stops."""
    from gyrotherm.daemon import Daemon

    frames, rel = build_frames(a.frames)
    done: queue.Queue[JSONDict] = queue.Queue()
    source = ScheduledSource(frames, rel, done.put)
    daemon = Daemon(_core_config(a))

    def commands() -> None:
        if not daemon.ready.wait(60.0):
            print("ERROR daemon not ready", flush=True)
            return
        # read back from the daemon's live rate publisher (private attribute: bench only)
        cc = getattr(getattr(getattr(daemon, "_sink", None), "rate", None),
                     "congestion_control", None)  # fmt: skip
        print("READY " + json.dumps({"rate_congestion_control": _cc_name(cc)}), flush=True)
        for line in sys.stdin:
            cmd = line.split()
            if not cmd or cmd[0] == "QUIT":
                break
            if cmd[0] == "PLAY":
                source.play(int(cmd[1]), float(cmd[2]))
                print("DONE " + json.dumps(done.get()), flush=True)
        daemon.stop()

    threading.Thread(target=commands, daemon=True).start()
    summary = daemon.run(source=source)
    print("SUMMARY " + json.dumps({"frames_received": summary.frames_received,
                                   "frames_published": summary.frames_published,
                                   "drops": summary.drops}), flush=True)  # fmt: skip
    return 0


# --- child role: bare zenoh publisher (the baseline) -----------------------------------


def role_bare(a: argparse.Namespace) -> int:
    """Like ``core`` but publishes pre-built rate messages directly (no daemon)."""
    import zenoh

    with open_session(listen=[a.listen]) as session:
        cc = (zenoh.CongestionControl.DROP if a.congestion == "drop"
              else zenoh.CongestionControl.BLOCK)  # fmt: skip
        pub = session.declare_publisher(keys(VEHICLE, BARE_SENSOR).rate, congestion_control=cc)
        print("READY " + json.dumps({"rate_congestion_control": _cc_name(pub.congestion_control)}),
              flush=True)  # fmt: skip
        seq = 0
        rel = [i / SENSOR_RATE_HZ for i in range(a.frames)]
        raw, bias, rate = (0.05, 0.1, 0.15), (0.01, 0.02, 0.03), (0.04, 0.08, 0.12)
        for line in sys.stdin:
            cmd = line.split()
            if not cmd or cmd[0] == "QUIT":
                break
            n, inv_speed = min(int(cmd[1]), a.frames), float(cmd[2])
            deadline = time.monotonic() + 30.0
            # zenoh's stub types matching_status as bool; it is a MatchingStatus object
            while not getattr(pub.matching_status, "matching", False) and (
                time.monotonic() < deadline
            ):
                time.sleep(0.01)
            put, clock, sleep = pub.put, time.time, time.sleep
            start = clock() + 0.05
            sleep(max(0.0, start - clock()))
            t_start = clock()
            for i in range(n):
                due = start + rel[i] * inv_speed
                if inv_speed:
                    wait = due - clock()
                    if wait > 0:
                        sleep(wait)
                put(encode_rate(RateMessage(seq, due, clock(), rate, raw, bias)))
                seq += 1
            now = clock()
            print("DONE " + json.dumps({"frames": n, "t_start_s": t_start, "t_end_s": now,
                  "final_lag_ms": round((now - due) * 1e3, 3) if inv_speed else None}),
                  flush=True)  # fmt: skip
        pub.undeclare()
    return 0


# --- orchestration -----------------------------------------------------------------------


class Chain:
    """One chain under test: its processes and how to play a trial through it."""

    name = ""

    def __init__(self) -> None:
        self.sub: LineChild | None = None
        self.pids: dict[str, int] = {}
        self.max_frames = 0

    def play(self, n_frames: int, inv_speed: float) -> JSONDict:
        raise NotImplementedError

    def expected(self, n_frames: int) -> tuple[int, int]:
        raise NotImplementedError

    def close(self) -> None:
        if self.sub is not None:
            self.sub.close()

    def start_sub(self, endpoint: str, *, sensor: str = SENSOR, health: bool = True,
                  slow_us: float = 0.0) -> None:
        args = ["--connect", endpoint, "--sensor", sensor, "--slow-us", str(slow_us)]
        self.sub = LineChild(f"{self.name}-sub", script_argv("sub", *args,
                             *([] if health else ["--no-health"])))  # fmt: skip
        self.sub.expect("READY", 60.0)
        self.pids["subscriber"] = self.sub.proc.pid


class ChildChain(Chain):
    """``core`` and ``bare``: the publisher is one of this script's roles."""

    def __init__(self, name: str, role: str, frames: list[can.Message], n_max: int,
                 calibration: Path, *, congestion: str = "block", slow_us: float = 0.0) -> None:
        super().__init__()
        self.name = name
        self._frames = frames
        self.max_frames = min(n_max, len(frames))
        ep = f"tcp/127.0.0.1:{free_port()}"
        self.pub = LineChild(name, script_argv(role, "--listen", ep, "--frames", str(n_max),
                                               "--calibration", str(calibration),
                                               "--congestion", congestion))  # fmt: skip
        self.ready_info: JSONDict = json.loads(self.pub.expect("READY", 60.0) or "{}")
        self.pids["daemon" if role == "core" else "publisher"] = self.pub.proc.pid
        self.start_sub(ep, sensor=SENSOR if role == "core" else BARE_SENSOR,
                       health=role == "core", slow_us=slow_us)  # fmt: skip
        self._bare = role == "bare"

    def expected(self, n_frames: int) -> tuple[int, int]:
        return (n_frames, 0) if self._bare else count_kinds(self._frames[:n_frames])

    def play(self, n_frames: int, inv_speed: float) -> JSONDict:
        out: JSONDict = json.loads(self.pub.ask(f"PLAY {n_frames} {inv_speed}", "DONE", 300.0))
        return out

    def close(self) -> None:
        self.pub.close()  # the publisher first: the daemon would log its peer leaving
        super().close()


class FullChain(Chain):
    """SocketcandServer here → ``gyrotherm run`` process → subscriber process."""

    name = "full"

    def __init__(self, frames: list[can.Message], rel: list[float], calibration: Path,
                 workdir: Path) -> None:
        from gyrotherm.daemon import load_config
        from gyrotherm.sim import SocketcandServer

        super().__init__()
        self._frames, self._rel = frames, rel
        self.max_frames = len(frames)
        self.server = SocketcandServer(host="127.0.0.1", port=0).start()
        zport = free_port()
        cfg = workdir / "daemon.toml"
        cfg.write_text(
            f'vehicle = "{VEHICLE}"\nsensor = "{SENSOR}"\ncalibration = "{calibration}"\n'
            "health_period_s = 0.1\n\n[can]\ninterface = \"socketcand\"\nchannel = \"vcan0\"\n"
            f'host = "127.0.0.1"\nport = {self.server.port}\nrecv_timeout_s = 0.1\n'
            "reopen_after_s = 3600.0\n\n"
            f'[zenoh]\nlisten = ["tcp/127.0.0.1:{zport}"]\n',
            encoding="utf-8",
        )
        self.config_path = cfg
        load_config(cfg)  # fail here, with the config error, rather than in the child
        self._log_path = workdir / "daemon.log"
        self._log: IO[str] = self._log_path.open("w", encoding="utf-8")
        self.daemon = subprocess.Popen(
            [sys.executable, "-m", "gyrotherm", "run", "--config", str(cfg),
             "--log-level", "info"], stdout=self._log, stderr=subprocess.STDOUT)  # fmt: skip
        self.pids["daemon"] = self.daemon.pid
        if not self.server.wait_for_clients(1, 60.0):
            raise RuntimeError(f"daemon did not connect to socketcand: {self.daemon_log()}")
        deadline = time.monotonic() + 60.0
        while "up:" not in self.daemon_log():
            if time.monotonic() > deadline or self.daemon.poll() is not None:
                raise RuntimeError(f"daemon did not come up: {self.daemon_log()}")
            time.sleep(0.05)
        self.start_sub(f"tcp/127.0.0.1:{zport}")
        self.pids["player"] = os.getpid()  # this process: SocketcandServer + play()

    def daemon_log(self) -> str:
        return self._log_path.read_text(encoding="utf-8", errors="replace")

    def expected(self, n_frames: int) -> tuple[int, int]:
        return count_kinds(self._frames[:n_frames])

    def play(self, n_frames: int, inv_speed: float) -> JSONDict:
        from gyrotherm.sim import FlushingSink, play

        frames = self._frames[:n_frames]
        dropped0 = sum(c.frames_dropped for c in self.server.client_stats())
        start = time.time() + 0.05 + 0.4e-6 * n_frames
        restamp(frames, self._rel, start, inv_speed or UNPACED_INV_SPEED)
        time.sleep(max(0.0, start - time.time()))
        if inv_speed:  # a bus that does not wait: the server drops when a queue is full
            stats = play(frames, self.server, speed=1.0, clock=time.time)
        else:  # back-pressure: wait for the daemon to read every 4096 frames
            stats = play(frames, FlushingSink(self.server, every_frames=4096, timeout_s=60.0),
                         speed=0, clock=time.time)  # fmt: skip
        self.server.flush(60.0)
        now = time.time()
        dropped = sum(c.frames_dropped for c in self.server.client_stats()) - dropped0
        return {"frames": stats.frames_sent, "t_start_s": now - stats.duration_s, "t_end_s": now,
                "final_lag_ms": round((now - frames[-1].timestamp) * 1e3, 3) if inv_speed
                else None, "socketcand_dropped": dropped}  # fmt: skip

    def close(self) -> None:
        super().close()
        if self.daemon.poll() is None:
            self.daemon.send_signal(signal.SIGTERM)
            try:
                self.daemon.wait(15.0)
            except subprocess.TimeoutExpired:
                self.daemon.kill()
                self.daemon.wait()
        self.server.shutdown()
        self._log.close()


def _cpu_snapshot(pids: dict[str, int]) -> JSONDict:
    return {"wall": time.monotonic(), "system": system_busy_seconds()[0],
            "roles": {role: thread_cpu_seconds(pid) for role, pid in pids.items()}}  # fmt: skip


def cpu_usage(before: JSONDict, after: JSONDict, n_rate: int) -> JSONDict:
    """CPU % per role (100 = one core), µs per rate frame per role and per thread of the
    daemon, the whole machine's busy % and what other processes used (``others_pct``)."""
    wall = after["wall"] - before["wall"]
    pct: dict[str, float] = {}
    per_frame: dict[str, float] = {}
    threads: dict[str, float] = {}
    for role, t1 in after["roles"].items():
        t0 = before["roles"].get(role, {})
        used = sum(t1.values()) - sum(v for k, v in t0.items() if k in t1)
        pct[role] = round(100 * used / wall, 1)
        per_frame[role] = round(1e6 * used / max(n_rate, 1), 2)
        if role == "daemon":
            threads = {k: round(1e6 * (v - t0.get(k, 0.0)) / max(n_rate, 1), 2)
                       for k, v in t1.items() if v - t0.get(k, 0.0) > 0}  # fmt: skip
    system = 100 * (after["system"] - before["system"]) / wall
    return {"pct": pct, "us_per_rate_frame": per_frame, "daemon_threads_us_per_rate_frame":
            threads, "system_busy_pct": round(system, 1),
            "others_pct": round(system - sum(pct.values()), 1)}  # fmt: skip


def run_trial(chain: Chain, n_frames: int, rate_fps: float | None, *,
              max_lag_ms: float, skip: int = 0) -> JSONDict:
    """One trial: ``rate_fps`` None = unpaced; else paced at that many rate frames/s.

    Latency and lag statistics leave out the first ``skip`` rate messages (warm-up)."""
    assert chain.sub is not None
    n_frames = min(n_frames, chain.max_frames)
    inv_speed = SENSOR_RATE_HZ / rate_fps if rate_fps else 0.0
    n_rate, n_state = chain.expected(n_frames)
    chain.sub.ask("MARK", "OK", 30.0)
    cpu0 = _cpu_snapshot(chain.pids)
    sent = chain.play(n_frames, inv_speed)
    expect_s = n_rate / rate_fps if rate_fps else 10.0
    got: JSONDict = json.loads(chain.sub.ask(
        f"WAIT {n_rate} {n_state} {30 + 3 * expect_s} 3.0 {skip}", "RESULT", 120 + 3 * expect_s))
    cpu = cpu_usage(cpu0, _cpu_snapshot(chain.pids), n_rate)
    daemon = got.get("daemon", {})
    loss = (n_rate - got["received_rate"]) + (n_state - got["received_state"])
    zero_loss = (loss == 0 and got["gaps"] == 0 and got["state_gaps"] == 0
                 and not daemon.get("drops") and not sent.get("socketcand_dropped"))
    span = (got["last_cb_s"] or sent["t_end_s"]) - sent["t_start_s"]
    result: JSONDict = {
        "chain": chain.name, "mode": "paced" if rate_fps else "unpaced",
        "target_rate_fps": rate_fps, "frames_sent": sent["frames"],
        "rate_frames": n_rate, "temperature_frames": n_state,
        "send_rate_fps": round(n_rate / max(sent["t_end_s"] - sent["t_start_s"], 1e-9), 1),
        "throughput_rate_fps": round(got["received_rate"] / span, 1) if span > 0 else None,
        "lost": loss, "zero_loss": zero_loss, "subscriber": got, "sender": sent,
        "cpu": cpu,
    }  # fmt: skip
    if not rate_fps:  # sensor time is not a send schedule when unpaced: no lag
        got.pop("lag", None)
    else:
        lag = got["lag"].get("p99_ms", math.inf)
        result["lag_p99_ms"] = lag
        result["kept_up"] = bool(zero_loss and lag < max_lag_ms)
    return result


def _line(r: JSONDict) -> str:
    s = r["subscriber"]
    txt = (f"  {r['chain']:5s} {r['mode']:8s} "
           f"{'' if r['target_rate_fps'] is None else format(r['target_rate_fps'], '.0f'):>7s} "
           f"→ {r['throughput_rate_fps'] or 0:9.0f} rate frames/s  rx {s['received_rate']}/"
           f"{r['rate_frames']} gaps {s['gaps']} lost {r['lost']}  "
           f"lat p50/p99 {s['latency'].get('p50_ms', math.nan):.2f}/"
           f"{s['latency'].get('p99_ms', math.nan):.2f} ms")  # fmt: skip
    if r["mode"] == "paced":
        txt += f"  lag p99 {r['lag_p99_ms']:.1f} ms kept_up={r['kept_up']}"
    c = r["cpu"]
    cpu = " ".join(f"{k}={v:.0f}%/{c['us_per_rate_frame'][k]:.1f}us" for k, v in c["pct"].items())
    return txt + f"  cpu {cpu} others={c['others_pct']:.0f}%"


def _cpu_median(trials: list[JSONDict], key: str) -> dict[str, float | None]:
    roles = trials[0]["cpu"][key] if trials else {}
    return {r: median([t["cpu"][key][r] for t in trials]) for r in roles}


def _summarise(trials: list[JSONDict], rate: float) -> JSONDict:
    out: JSONDict = {}
    for chain in sorted({t["chain"] for t in trials}):
        mine = [t for t in trials if t["chain"] == chain]
        unp = [t for t in mine if t["mode"] == "unpaced"]
        pac = [t for t in mine if t["mode"] == "paced" and t["target_rate_fps"] == rate]
        ladder = sorted({t["target_rate_fps"] for t in mine if t["mode"] == "paced"})
        kept: list[float] = []  # rates that kept up, each with every lower rate tried
        for r in ladder:
            if not all(t["kept_up"] for t in mine if t["target_rate_fps"] == r):
                break
            kept.append(r)
        out[chain] = {
            "unpaced_trials": len(unp),
            "unpaced_zero_loss_all": all(t["zero_loss"] for t in unp),
            "unpaced_throughput_median_fps": median([t["throughput_rate_fps"] for t in unp]),
            "unpaced_latency_p99_median_ms": median(
                [t["subscriber"]["latency"].get("p99_ms") for t in unp]),
            "unpaced_cpu_pct_median": _cpu_median(unp, "pct"),
            "unpaced_cpu_us_per_rate_frame_median": _cpu_median(unp, "us_per_rate_frame"),
            "unpaced_others_cpu_pct_median": median([t["cpu"]["others_pct"] for t in unp]),
            "paced_rate_fps": rate,
            "paced_trials": len(pac),
            "paced_kept_up_all": all(t["kept_up"] for t in pac) if pac else None,
            "paced_zero_loss_all": all(t["zero_loss"] for t in pac) if pac else None,
            "paced_throughput_median_fps": median([t["throughput_rate_fps"] for t in pac]),
            "paced_lag_p99_median_ms": median([t["lag_p99_ms"] for t in pac]),
            "paced_latency_p99_median_ms": median(
                [t["subscriber"]["latency"].get("p99_ms") for t in pac]),
            "paced_cpu_pct_median": _cpu_median(pac, "pct"),
            "paced_cpu_us_per_rate_frame_median": _cpu_median(pac, "us_per_rate_frame"),
            "paced_others_cpu_pct_median": median([t["cpu"]["others_pct"] for t in pac]),
            "paced_rates_tried_fps": ladder,
            "max_paced_rate_kept_up_fps": max(kept) if kept else None,
        }  # fmt: skip
    return out


def orchestrate(a: argparse.Namespace) -> JSONDict:
    t_begin = time.monotonic()
    n_rate_max = int(max([a.rate, *a.ladder]) * a.trial_s)
    n_unpaced = int(a.unpaced_frames)
    result: JSONDict = {"bench": "stream_throughput", "machine": machine(),
                        "settings": {"trials": a.trials, "trial_s": a.trial_s, "rate_fps": a.rate,
                                     "unpaced_frames": n_unpaced, "ladder_fps": a.ladder,
                                     "max_lag_ms": a.max_lag_ms, "chains": a.chains}}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="gyrotherm-bench-") as tmp:
        work = Path(tmp)
        log("throughput: fitting a calibration, building frames ...")
        cal = fit_calibration(work)
        frames, rel = build_frames(max(n_rate_max, n_unpaced))
        n_max = len(frames)
        chains: list[Chain] = []
        try:
            for name in a.chains:
                log(f"throughput: starting chain {name} ...")
                if name == "full":
                    chains.append(FullChain(frames, rel, cal, work))
                else:
                    chains.append(ChildChain(name, "core" if name == "core" else "bare",
                                             frames, n_max, cal))  # fmt: skip
            for c in chains:
                if isinstance(c, ChildChain) and c.name == "core":
                    result["daemon_rate_congestion_control"] = c.ready_info.get(
                        "rate_congestion_control")
            trials: list[JSONDict] = []
            n_paced = prefix_for(frames, int(a.rate * a.trial_s))
            n_unpaced_frames = prefix_for(frames, n_unpaced)
            for k in range(a.trials):
                for chain in chains:
                    for rate in (None, a.rate):
                        r = run_trial(chain, n_unpaced_frames if rate is None else n_paced, rate,
                                      max_lag_ms=a.max_lag_ms)  # fmt: skip
                        r["round"] = k
                        trials.append(r)
                        log(_line(r))
            for rate in a.ladder:
                for chain in chains:
                    r = run_trial(chain, prefix_for(frames, int(rate * a.trial_s)), rate,
                                  max_lag_ms=a.max_lag_ms)
                    r["round"] = "ladder"
                    trials.append(r)
                    log(_line(r))
            result["memory"] = {c.name: {role: memory_kb(pid) for role, pid in c.pids.items()
                                         if role in ("daemon", "subscriber")}
                                for c in chains}  # fmt: skip
        finally:
            for c in chains:
                c.close()
        if a.congestion_check and "core" in a.chains:
            result["congestion_control_check"] = congestion_check(a, frames, cal)
    result["trials"] = trials
    result["summary"] = _summarise(trials, a.rate)
    result["ratios"] = _ratios(result["summary"], a.rate)
    result["elapsed_s"] = round(time.monotonic() - t_begin, 1)
    return result


def congestion_check(a: argparse.Namespace, frames: list[can.Message], cal: Path) -> JSONDict:
    """Unpaced into a subscriber slowed by ``--slow-us``: the daemon (BLOCK), then the
    negative control, the bare publisher with DROP."""
    out: JSONDict = {"slow_us": a.slow_us, "rate_frames": a.check_frames}
    n = prefix_for(frames, a.check_frames)
    for key, role, cc in (("daemon_block", "core", "block"), ("bare_drop", "bare", "drop")):
        log(f"throughput: {role} ({cc}) into a subscriber slowed by {a.slow_us:g} µs ...")
        chain = ChildChain(f"{role}-{cc}-slowsub", role, frames, n, cal, congestion=cc,
                           slow_us=a.slow_us)  # fmt: skip
        try:
            r = run_trial(chain, n, None, max_lag_ms=a.max_lag_ms)
        finally:
            chain.close()
        log(_line(r))
        out[key] = {"congestion_control": chain.ready_info.get("rate_congestion_control"),
                    "zero_loss": r["zero_loss"], "lost": r["lost"],
                    "expected_rate": r["rate_frames"],
                    "received_rate": r["subscriber"]["received_rate"],
                    "gaps": r["subscriber"]["gaps"], "missing": r["subscriber"]["missing"],
                    "send_rate_fps": r["send_rate_fps"],
                    "throughput_rate_fps": r["throughput_rate_fps"],
                    "latency_p99_ms": r["subscriber"]["latency"].get("p99_ms")}  # fmt: skip
    out["daemon_block_is_lossless"] = out["daemon_block"]["zero_loss"]
    out["bare_drop_loses"] = not out["bare_drop"]["zero_loss"]
    return out


def _ratios(summary: JSONDict, rate: float) -> JSONDict:
    out: JSONDict = {"requirement_fps": 50_000,
                     "saturated_1mbit_can_fps": round(CAN_1MBIT_FRAMES_S),
                     "saturated_1mbit_can_stuffed_fps": round(1e6 / _STUFFED_FRAME_BITS)}
    bare = (summary.get("bare") or {}).get("unpaced_throughput_median_fps")
    for name, s in summary.items():
        thr = s.get("unpaced_throughput_median_fps")
        if thr:
            out[f"{name}_unpaced_vs_requirement"] = round(thr / 50_000, 3)
            out[f"{name}_unpaced_vs_saturated_can"] = round(thr / CAN_1MBIT_FRAMES_S, 2)
            if bare and name != "bare":
                out[f"{name}_unpaced_vs_bare"] = round(thr / bare, 3)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("--role", choices=["orchestrate", "sub", "core", "bare"], default="orchestrate")
    p.add_argument("--trials", type=int, default=3, help="rounds of every chain and mode")
    p.add_argument("--rate", type=float, default=50_000.0, help="paced rate, rate frames/s")
    p.add_argument("--trial-s", type=float, default=3.0, help="paced trial length, s")
    p.add_argument("--unpaced-frames", type=int, default=150_000,
                   help="rate frames per unpaced trial")
    p.add_argument("--ladder", type=float, nargs="*", default=[],
                   help="extra paced rates (rate frames/s), one trial each")
    p.add_argument("--max-lag-ms", type=float, default=50.0)
    p.add_argument("--chains", nargs="+", default=["bare", "core", "full"],
                   choices=["bare", "core", "full"])  # fmt: skip
    p.add_argument("--no-congestion-check", dest="congestion_check", action="store_false",
                   help="skip the slow-subscriber check (daemon BLOCK; bare DROP as control)")
    p.add_argument("--slow-us", type=float, default=40.0,
                   help="congestion check: subscriber busy time per message, µs")
    p.add_argument("--check-frames", type=int, default=80_000,
                   help="congestion check: rate frames per trial")
    # child roles
    p.add_argument("--connect", help=argparse.SUPPRESS)
    p.add_argument("--listen", help=argparse.SUPPRESS)
    p.add_argument("--sensor", default=SENSOR, help=argparse.SUPPRESS)
    p.add_argument("--no-health", dest="health", action="store_false", help=argparse.SUPPRESS)
    p.add_argument("--frames", type=int, default=0, help=argparse.SUPPRESS)
    p.add_argument("--calibration", help=argparse.SUPPRESS)
    p.add_argument("--congestion", default="block", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.role == "sub":
        return role_sub(a)
    if a.role == "core":
        return role_core(a)
    if a.role == "bare":
        return role_bare(a)
    result = orchestrate(a)
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
