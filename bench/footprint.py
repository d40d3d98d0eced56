"""Footprint of ``gyrotherm run``: import time, time to READY=1, steady RSS at 2 kHz; before/after.

Two source trees, run with the same interpreter and venv (``PYTHONPATH=<tree>/src``):
BEFORE = ``--before-ref`` (default 7f136f8, the last commit whose daemon estimator ran on
filterpy; checked out into a temporary ``git worktree`` that is removed at the end; or an
existing checkout, ``--before-src``), AFTER = this working tree. Measured, interleaved
(before, after, bare, before, ...):

1. **import**: ``--import-trials`` fresh interpreters each import what ``gyrotherm
   run`` imports before the daemon starts: ``gyrotherm.cli``, parse ``run --config X``
   as ``main`` does (``cli.parse_args`` where the tree has it, else
   ``build_parser()``), the command's module, ``gyrotherm.daemon``. Per interpreter:
   seconds spent importing (``perf_counter`` around it), VmRSS afterwards, module
   count, which offline modules got loaded; and the parent's spawn → exit wall time.
   Reference rows in the same rounds: ``numpy`` alone; ``deps`` = numpy + zenoh +
   python-can + msgpack (the testers' baseline); ``deps_cantools`` (+ cantools, the
   DBC codec the daemon needs); ``filterpy`` = numpy + ``from filterpy.kalman import
   KalmanFilter``
   (filterpy's ``__init__`` imports all its subpackages: scipy.stats, scipy.linalg,
   scipy.ndimage).
2. **ready**: ``python -m gyrotherm run --config FILE`` spawned with ``NOTIFY_SOCKET``
   = a unix datagram socket bound here (as systemd does, Type=notify); time from
   just before the spawn to the datagram holding ``READY=1`` (``--ready-trials``
   runs that stop there, plus the start of each ``--daemon-trials`` run). After
   READY the socket is read on, as systemd does: left unread, its queue
   (``net.unix.max_dgram_qlen`` datagrams, 10 here) fills and each later
   notification blocks the daemon's loop for the notifier's send timeout. The bus is a
   ``SocketcandServer`` (from this tree's simulator) on 127.0.0.1; the daemon
   connects with its ``socketcand`` interface. VmRSS at READY. The same-run baseline,
   interleaved with them: ``bare`` = a fresh interpreter that imports numpy + zenoh +
   python-can + msgpack + cantools and then sends ``READY=1`` the same way (spawn →
   READY of the bare import), and ``bare_session`` = the same plus opening a zenoh
   session listening on loopback (what any zenoh publisher pays before it is ready).
3. **steady**: right after READY, ``--steady-s`` s of a synthetic 3-axis gyro at
   ``--rate-hz`` rate frames/s (sensor time = schedule; temperature frames every
   0.1 s) played onto the server, a raw zenoh subscriber here counting the rate
   samples; VmRSS sampled every 0.5 s. Steady RSS = median of the samples in the
   last 5 s; also the last sample and VmHWM. Then SIGTERM; the daemon's closing
   line ``frames in N, published M, dropped D`` must account for every frame sent.

4. **cpu** (per-frame CPU): the daemon's per-frame core, ``Pipeline.process`` (decode →
   estimate → compensate → encode → a sink that discards), in a child per tree and
   trial, interleaved, over the same pre-built frames of a 1 kHz gyro (seeded; as
   bench/effects_cost.py), the fitted paper calibration: ``daemon`` = 10 Hz temperature
   frames (1 % of the frames, the daemon's stream), ``temperature`` = a temperature
   frame with every rate frame (isolates the estimator, which runs per temperature
   frame). CPU time of the child (``process_time``) around the loop, best of
   ``--cpu-passes`` passes per child; medians over ``--cpu-trials`` rounds.

Bytecode. gyrotherm is installed from a wheel on a vehicle (docs/operations.md): pip
writes every module's ``.pyc`` at install, and the unit's ``PYTHONDONTWRITEBYTECODE=1``
only stops it writing more. A source tree under the same variable (this machine sets it)
compiles every gyrotherm module from source at every start, ≈ 0.1 s that no vehicle
pays, while the dependencies' ``.pyc`` from their wheels are there. So by default
(``--bytecode compiled``) both trees are byte-compiled first (``compileall``, into their
``__pycache__`` directories, which git ignores; the ones this run created are removed at
the end); ``--bytecode source`` measures the trees as they are.

Prints one JSON object on stdout (medians, ratios after/before, every sample), a
human summary on stderr. Nothing asserts: a measurement. ``--quick``: fewer and
shorter trials. Loopback only; zenoh sessions without scouting.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.codecs import FrameEncoder, Run
from stream_throughput import free_port, log, machine, memory_kb

BENCH_DIR = Path(__file__).resolve().parent
REPO = BENCH_DIR.parent
AFTER_SRC = REPO / "src"
VEHICLE, SENSOR = "bench", "imu0"
TEMPERATURE_PERIOD_S = 0.1
READY_TIMEOUT_S = 120.0
#: Modules the vehicle path should not load (reported per import sample).
OFFLINE = ("gyrotherm.sim", "gyrotherm.analysis", "gyrotherm.client", "matplotlib",
           "scipy.signal", "scipy.stats", "scipy", "filterpy")  # fmt: skip

RUN_PATH = """
import gyrotherm.cli as cli
argv = ["run", "--config", "x.toml"]
# as main() parses it: cli.parse_args (the run parser alone) where the tree has it
args = cli.parse_args(argv) if hasattr(cli, "parse_args") else cli.build_parser().parse_args(argv)
__import__(args.func.__module__)
import gyrotherm.daemon
"""
REFERENCE = {
    "numpy": "import numpy",
    "deps": "import numpy, zenoh, can, msgpack",
    "deps_cantools": "import numpy, zenoh, can, msgpack, cantools",
    "filterpy": "import numpy\nfrom filterpy.kalman import KalmanFilter",
}
IMPORT_CHILD = """
import time
t0 = time.perf_counter()
{code}
dt = time.perf_counter() - t0
import json, sys
rss = 0
with open("/proc/self/status") as f:
    for line in f:
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1])
offline = {offline!r}
print(json.dumps({{"import_s": dt, "rss_kB": rss, "modules": len(sys.modules),
                  "loaded": [p for p in offline if p in sys.modules],
                  "gyrotherm": sys.modules["gyrotherm"].__file__
                  if "gyrotherm" in sys.modules else None}}))
"""

JSONDict = dict[str, Any]

#: The same-run READY baselines (see the module docstring): import, (session), notify.
BARE_READY = {
    "bare": "",
    "bare_session": """
import zenoh
_config = zenoh.Config()
_config.insert_json5("scouting/multicast/enabled", "false")
_config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
_session = zenoh.open(_config)
""",
}
BARE_CHILD = """
import os, signal, socket
import numpy, zenoh, can, msgpack, cantools
{extra}
with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as _s:
    _s.sendto(b"READY=1", os.environ["NOTIFY_SOCKET"])
signal.pause()
"""


def median(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def _env(src: Path | None, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NOTIFY_SOCKET")}
    if src is not None:
        env["PYTHONPATH"] = str(src)
    env.update(extra)
    return env


# --- 1. imports ---------------------------------------------------------------------------


def import_sample(code: str, src: Path | None) -> JSONDict:
    child = IMPORT_CHILD.format(code=textwrap.dedent(code).strip(), offline=OFFLINE)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                          env=_env(src), cwd=tempfile.gettempdir(), timeout=120)  # fmt: skip
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"import child failed: {done.stderr[-2000:]}")
    out: JSONDict = json.loads(done.stdout)
    out["wall_s"] = wall
    return out


def measure_imports(trees: dict[str, Path], trials: int) -> JSONDict:
    variants: dict[str, tuple[str, Path | None]] = {
        **{f"run_{name}": (RUN_PATH, src) for name, src in trees.items()},
        **{name: (code, None) for name, code in REFERENCE.items()},
    }
    samples: dict[str, list[JSONDict]] = {v: [] for v in variants}
    for k in range(trials):
        for name, (code, src) in variants.items():
            s = import_sample(code, src)
            samples[name].append(s)
        log(f"import round {k + 1}/{trials}: " + "  ".join(
            f"{n} {s[-1]['import_s'] * 1e3:.0f} ms" for n, s in samples.items()))
    for name, (_, src) in variants.items():
        if src is not None:
            where = {s["gyrotherm"] for s in samples[name]}
            if where != {str(src / "gyrotherm" / "__init__.py")}:
                raise RuntimeError(f"{name}: imported gyrotherm from {where}, not {src}")
    summary = {name: {
        "import_s_median": round(median([s["import_s"] for s in ss]) or 0, 4),
        "wall_s_median": round(median([s["wall_s"] for s in ss]) or 0, 4),
        "rss_kB_median": median([s["rss_kB"] for s in ss]),
        "modules": median([s["modules"] for s in ss]),
        "loaded": ss[0]["loaded"],
    } for name, ss in samples.items()}  # fmt: skip
    return {"summary": summary, "samples": samples}


# --- 2./3. a daemon: READY, then steady state at rate_hz -----------------------------------


def synthetic_run(seconds: float, rate_hz: float) -> Run:
    """A 3-axis gyro at ``rate_hz`` for ``seconds``: biased noise, 20 → 45 °C."""
    n = int(seconds * rate_hz)
    rng = np.random.default_rng(1)
    t = np.arange(n) / rate_hz
    temp = 20.0 + 25.0 * t / max(float(t[-1]), 1e-9)
    rates = {a: 0.05 * (i + 1) + 0.01 * rng.standard_normal(n) for i, a in enumerate("xyz")}
    return Run("bench-footprint", t, temp, rates,
               metadata={"temperature_period_s": str(TEMPERATURE_PERIOD_S)})  # fmt: skip


def fit_calibration(directory: Path) -> Path:
    from gyrotherm.compensation import features, fit
    from gyrotherm.estimators import EstimatorConfig
    from gyrotherm.sim import GyroParams, chamber_runs

    runs = chamber_runs([5, 20, 60], seed=8, rate_hz=1.0, hold_s=1200)
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    cal = fit([features(r, est) for r in runs], "paper", estimator=est)
    return cal.save(directory / "footprint.calibration.json")


def _vm(pid: int) -> JSONDict:
    try:
        return memory_kb(pid)
    except OSError:
        return {}


class _RateCounter:
    """Raw zenoh subscribers on the sensor's rate and state keys (no decoding): counts
    the rate samples; the state subscription makes the daemon publish state as on a
    vehicle with a consumer."""

    def __init__(self, endpoint: str) -> None:
        from gyrotherm._zenoh import keys, open_session

        self.count = 0
        self._lock = threading.Lock()
        k = keys(VEHICLE, SENSOR)
        self._session = open_session(mode="client", connect=[endpoint])
        self._subs = [self._session.declare_subscriber(k.rate, self._on),
                      self._session.declare_subscriber(k.state, lambda _s: None)]

    def _on(self, _sample: object) -> None:
        with self._lock:
            self.count += 1

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._session.close()


def _drain(sock: socket.socket, notes: list[str]) -> None:
    """Read notifications until the socket is closed (at the end of the trial)."""
    sock.settimeout(0.2)
    while sock.fileno() != -1:
        try:
            notes.append(sock.recv(4096).decode(errors="replace"))
        except TimeoutError:
            continue
        except OSError:
            return


@contextmanager
def notify_socket(directory: Path) -> Iterator[tuple[socket.socket, str]]:
    path = str(directory / f"notify-{os.getpid()}-{time.monotonic_ns()}.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(path)
        try:
            yield sock, path
        finally:
            os.unlink(path)


def daemon_trial(src: Path, calibration: Path, frames: list[Any], work: Path,
                 steady_s: float, *, ready_only: bool = False) -> JSONDict:
    from gyrotherm.sim import SocketcandServer
    from gyrotherm.sim._stream import play

    zport = free_port()
    out: JSONDict = {}
    rel_s = [f.timestamp - frames[0].timestamp for f in frames]  # sensor-time schedule
    with SocketcandServer(host="127.0.0.1", port=0) as server, notify_socket(work) as (sock, path):
        cfg = work / "footprint.toml"
        cfg.write_text(
            f'vehicle = "{VEHICLE}"\nsensor = "{SENSOR}"\ncalibration = "{calibration}"\n'
            "health_period_s = 1.0\n\n[can]\ninterface = \"socketcand\"\nchannel = \"vcan0\"\n"
            f'host = "127.0.0.1"\nport = {server.port}\nrecv_timeout_s = 0.1\n'
            "reopen_after_s = 3600.0\n\n"  # no reconnect while the bench sets up or idles
            f'[zenoh]\nlisten = ["tcp/127.0.0.1:{zport}"]\n', encoding="utf-8")  # fmt: skip
        log_path = work / "daemon.log"
        with log_path.open("w", encoding="utf-8") as log_file:
            t0 = time.monotonic()
            proc = subprocess.Popen(
                [sys.executable, "-m", "gyrotherm", "run", "--config", str(cfg),
                 "--log-level", "info"], stdout=subprocess.PIPE, stderr=log_file, text=True,
                env=_env(src, NOTIFY_SOCKET=path), cwd=work)  # fmt: skip
            try:
                sock.settimeout(READY_TIMEOUT_S)
                while True:
                    data = sock.recv(4096).decode()
                    if "READY=1" in data.splitlines():
                        break
                out["ready_s"] = time.monotonic() - t0
                out["at_ready"] = _vm(proc.pid)
                # keep reading the notify socket, as systemd does: left unread, its queue
                # fills and every later sd_notify send blocks the daemon's loop
                notes: list[str] = []
                threading.Thread(target=_drain, args=(sock, notes), daemon=True).start()
                if not server.wait_for_clients(1, 30.0):
                    raise RuntimeError("the daemon is READY but not connected to socketcand")
                if ready_only:
                    proc.send_signal(signal.SIGTERM)
                    proc.communicate(timeout=30.0)
                    out["returncode"] = proc.returncode
                    return out
                counter = _RateCounter(f"tcp/127.0.0.1:{zport}")
                try:
                    rss: list[tuple[float, int]] = []
                    done = threading.Event()

                    def sample() -> None:
                        start = time.monotonic()
                        while not done.wait(0.5):
                            vm = _vm(proc.pid)
                            if "VmRSS_kB" in vm:
                                rss.append((time.monotonic() - start, vm["VmRSS_kB"]))

                    sampler = threading.Thread(target=sample, daemon=True)
                    sampler.start()
                    # frames carry wall-clock stamps on the send schedule, as a bus would
                    start = time.time() + 0.05
                    for f, rel in zip(frames, rel_s, strict=True):
                        f.timestamp = start + rel
                    stats = play(frames, server, speed=1.0, clock=time.time)
                    t_flush = time.monotonic()
                    out["flushed"] = server.flush(60.0)
                    out["flush_s"] = round(time.monotonic() - t_flush, 3)
                    out["socketcand"] = [{"sent": c.frames_sent, "dropped": c.frames_dropped}
                                         for c in server.client_stats()]
                    done.set()
                    sampler.join()
                    out["at_end"] = _vm(proc.pid)
                    deadline = time.monotonic() + 30.0
                    while counter.count < stats.rate_frames and time.monotonic() < deadline:
                        time.sleep(0.05)
                    out["subscriber_rate_received"] = counter.count
                finally:
                    counter.close()
                proc.send_signal(signal.SIGTERM)
                stdout, _ = proc.communicate(timeout=30.0)
                out["notifications"] = len(notes)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
        tail = [x for x in stdout.splitlines() if x.startswith("frames in")]
        m = re.search(r"frames in (\d+), published (\d+), dropped (\d+)", tail[-1] if tail else "")
        out.update(returncode=proc.returncode, frames_sent=stats.frames_sent,
                   rate_frames_sent=stats.rate_frames, play_s=round(stats.duration_s, 3),
                   achieved_rate_hz=round(stats.rate_frames / stats.duration_s, 1))
        out["daemon_summary"] = tail[-1] if tail else None
        if m:
            out.update(frames_in=int(m[1]), published=int(m[2]), dropped=int(m[3]))
        # every frame sent reached the daemon and was published or dropped for a reason
        out["accounted"] = m is not None and (int(m[1]) == stats.frames_sent
                                              and int(m[2]) + int(m[3]) == int(m[1]))
        if not out["accounted"]:
            out["daemon_log_tail"] = log_path.read_text(errors="replace")[-3000:]
        last = [kb for t, kb in rss if t >= max(0.0, steady_s - 5.0)]
        out["rss_steady_kB"] = median([float(x) for x in last])
        out["rss_samples"] = rss
    return out


def bare_trial(name: str, work: Path) -> JSONDict:
    """Spawn → READY=1 of a bare import of the daemon's dependencies (module docstring)."""
    out: JSONDict = {}
    with notify_socket(work) as (sock, path):
        t0 = time.monotonic()
        proc = subprocess.Popen([sys.executable, "-c", BARE_CHILD.format(extra=BARE_READY[name])],
                                env=_env(None, NOTIFY_SOCKET=path), cwd=work,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
        try:
            sock.settimeout(READY_TIMEOUT_S)
            while "READY=1" not in sock.recv(4096).decode().splitlines():
                pass
            out["ready_s"] = time.monotonic() - t0
            out["at_ready"] = _vm(proc.pid)
            proc.send_signal(signal.SIGTERM)
            proc.communicate(timeout=30.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return out


def measure_ready(trees: dict[str, Path], trials: int, work: Path) -> JSONDict:
    """Spawn → READY=1 only (no frames), interleaved with the bare baselines: more samples
    of the noisiest figure."""
    calibration = fit_calibration(work)
    samples: dict[str, list[JSONDict]] = {name: [] for name in [*trees, *BARE_READY]}
    for k in range(trials):
        for name, src in trees.items():
            r = daemon_trial(src, calibration, [], work, 0.0, ready_only=True)
            samples[name].append(r)
        for name in BARE_READY:
            samples[name].append(bare_trial(name, work))
        log(f"ready round {k + 1}/{trials}: " + "  ".join(
            f"{n} {s[-1]['ready_s']:.2f} s" for n, s in samples.items()))
    summary = {name: {
        "ready_s_median": round(median([r["ready_s"] for r in rs]) or 0, 3),
        "rss_at_ready_kB_median": median([r["at_ready"].get("VmRSS_kB", 0) for r in rs]),
    } for name, rs in samples.items()}  # fmt: skip
    return {"summary": summary, "samples": samples}


def measure_daemons(trees: dict[str, Path], trials: int, steady_s: float, rate_hz: float,
                    work: Path) -> JSONDict:
    calibration = fit_calibration(work)
    frames = list(_frames(steady_s, rate_hz))
    samples: dict[str, list[JSONDict]] = {name: [] for name in trees}
    for k in range(trials):
        for name, src in trees.items():
            r = daemon_trial(src, calibration, frames, work, steady_s)
            samples[name].append(r)
            log(f"daemon round {k + 1}/{trials} {name}: READY {r['ready_s']:.2f} s, "
                f"RSS at READY {r['at_ready'].get('VmRSS_kB')} kB, steady {r['rss_steady_kB']} "
                f"kB, HWM {r['at_end'].get('VmHWM_kB')} kB; {r['achieved_rate_hz']} Hz, "
                f"accounted {r['accounted']}, subscriber {r['subscriber_rate_received']}/"
                f"{r['rate_frames_sent']}")
    summary = {name: {
        "ready_s_median": round(median([r["ready_s"] for r in rs]) or 0, 3),
        "rss_at_ready_kB_median": median([r["at_ready"].get("VmRSS_kB", 0) for r in rs]),
        "rss_steady_kB_median": median([r["rss_steady_kB"] for r in rs
                                        if r["rss_steady_kB"] is not None]),
        "hwm_kB_median": median([r["at_end"].get("VmHWM_kB", 0) for r in rs]),
        "achieved_rate_hz_median": median([r["achieved_rate_hz"] for r in rs]),
        "all_frames_accounted": all(r["accounted"] for r in rs),
    } for name, rs in samples.items()}  # fmt: skip
    return {"summary": summary, "samples": samples}


def _frames(steady_s: float, rate_hz: float) -> Iterator[Any]:
    from gyrotherm.sim._stream import frames_from_run

    return iter(frames_from_run(synthetic_run(steady_s, rate_hz), encoder=FrameEncoder()))


# --- 4. per-frame CPU of the pipeline ------------------------------------------------------

CPU_CHILD = """
import json, sys, time
import numpy as np
from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run
from gyrotherm.compensation import load_calibration
from gyrotherm.daemon import Pipeline
from gyrotherm.sim import frames_from_run

cal_path, n_rate, period_s, passes = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), \\
    int(sys.argv[4])
rng = np.random.default_rng(1)
t = np.arange(n_rate) / 1000.0
temp = 20.0 + 10.0 * np.sin(2 * np.pi * t / max(float(t[-1]), 1.0))  # heats and cools
rates = {a: 0.1 + 0.01 * rng.standard_normal(n_rate) for a in "xyz"}
run = Run("bench-footprint-cpu", t, temp, rates,
          metadata={"temperature_period_s": str(period_s)})
msgs = list(frames_from_run(run, encoder=FrameEncoder(), t0_s=1_700_000_000.0))
temp_id = FrameEncoder().layout.temperature.frame_id
cal = load_calibration(cal_path)


class Discard:
    def put_rate(self, payload):
        return None

    def put_state(self, payload):
        return None


cpu = []
for _ in range(passes):
    pipe = Pipeline(FrameDecoder(), Discard(), calibration=cal)
    process = pipe.process
    t0 = time.process_time()
    for m in msgs:
        process(m, 1_700_000_000.0)
    cpu.append(time.process_time() - t0)
    c = pipe.counters()
    assert c.frames_published == len(msgs), c  # everything through, nothing dropped
print(json.dumps({"frames": len(msgs), "cpu_s": cpu,
                  "temperature_frames": sum(m.arbitration_id == temp_id for m in msgs),
                  "filterpy_loaded": "filterpy" in sys.modules}))
"""
CPU_STREAMS = {"daemon": 0.1, "temperature": 0.001}


def measure_cpu(trees: dict[str, Path], trials: int, passes: int, n_rate: int,
                work: Path) -> JSONDict:
    calibration = fit_calibration(work)
    samples: dict[str, dict[str, list[JSONDict]]] = {
        stream: {name: [] for name in trees} for stream in CPU_STREAMS}
    for k in range(trials):
        for stream, period_s in CPU_STREAMS.items():
            for name, src in trees.items():
                done = subprocess.run(
                    [sys.executable, "-c", CPU_CHILD, str(calibration), str(n_rate),
                     str(period_s), str(passes)], capture_output=True, text=True,
                    env=_env(src), cwd=work, timeout=600)  # fmt: skip
                if done.returncode != 0:
                    raise RuntimeError(f"cpu child failed: {done.stderr[-2000:]}")
                r = json.loads(done.stdout)
                r["us_per_frame"] = 1e6 * min(r["cpu_s"]) / r["frames"]
                samples[stream][name].append(r)
            log(f"cpu round {k + 1}/{trials} {stream}: " + "  ".join(
                f"{n} {s[-1]['us_per_frame']:.2f} µs/frame" for n, s in samples[stream].items()))
    summary: JSONDict = {}
    for stream, by_tree in samples.items():
        summary[stream] = {name: {
            "us_per_frame_median": _round(median([r["us_per_frame"] for r in rs]), 3),
            "frames": rs[0]["frames"], "temperature_frames": rs[0]["temperature_frames"],
        } for name, rs in by_tree.items()}  # fmt: skip
        summary[stream]["after_over_before"] = _ratio(
            summary[stream]["after"]["us_per_frame_median"],
            summary[stream]["before"]["us_per_frame_median"])
        summary[stream]["after_over_before_paired"] = _paired(
            by_tree, "after", "before", lambda r: r["us_per_frame"])
    return {"summary": summary, "samples": samples}


# --- before tree, ratios, main ------------------------------------------------------------


@contextmanager
def compiled(srcs: list[Path]) -> Iterator[list[str]]:
    """Byte-compile each tree's gyrotherm package (as pip does at install); remove the
    ``__pycache__`` directories that were not there before at the end."""
    created: list[Path] = []
    for src in srcs:
        pkg = src / "gyrotherm"
        before = set(pkg.rglob("__pycache__"))
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(pkg)], check=True,
                       env=_env(None), capture_output=True)  # fmt: skip
        created += [d for d in pkg.rglob("__pycache__") if d not in before]
    try:
        yield [str(d) for d in created]
    finally:
        for d in created:
            for f in d.glob("*.pyc"):
                f.unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                d.rmdir()


@contextmanager
def before_tree(a: argparse.Namespace) -> Iterator[Path]:
    if a.before_src is not None:
        yield Path(a.before_src).resolve()
        return
    tmp = Path(tempfile.mkdtemp(prefix="gyrotherm-before-"))
    path = tmp / "tree"
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(path),
                    a.before_ref], check=True, capture_output=True)  # fmt: skip
    try:
        yield path / "src"
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(path)],
                       check=False, capture_output=True)  # fmt: skip
        tmp.rmdir() if tmp.exists() and not any(tmp.iterdir()) else None


def _ratio(after: float | None, before: float | None) -> float | None:
    return round(after / before, 3) if after and before else None


def _paired(samples: JSONDict, after: str, before: str, key: Any) -> float | None:
    """Median over rounds of after/before within each round (load changes hit both)."""
    pairs = zip(samples.get(after, []), samples.get(before, []), strict=False)
    return _round(median([key(x) / key(y) for x, y in pairs if key(y)]))


def _round(v: float | None, digits: int = 3) -> float | None:
    return None if v is None else round(v, digits)


def ratios(imports: JSONDict, daemons: JSONDict, ready: JSONDict) -> JSONDict:
    """after / before: of the medians, and the median of per-round paired ratios."""
    i, d = imports["summary"], daemons["summary"]
    out: JSONDict = {}
    if i:
        for key in ("import_s_median", "wall_s_median", "rss_kB_median", "modules"):
            out[f"import_{key}"] = _ratio(i["run_after"][key], i["run_before"][key])
        out["import_s_paired_median"] = _paired(imports["samples"], "run_after", "run_before",
                                                lambda s: s["import_s"])
    if d:
        for key in ("ready_s_median", "rss_at_ready_kB_median", "rss_steady_kB_median",
                    "hwm_kB_median"):
            out[key] = _ratio(d["after"][key], d["before"][key])
        out["ready_s_paired_median"] = _paired(daemons["samples"], "after", "before",
                                               lambda r: r["ready_s"])
    r = ready["summary"]
    if r:
        out["ready_only_s_median"] = _ratio(r["after"]["ready_s_median"],
                                            r["before"]["ready_s_median"])
        out["ready_only_s_paired_median"] = _paired(ready["samples"], "after", "before",
                                                    lambda x: x["ready_s"])
    return out


def ratios_to_bare(imports: JSONDict, ready: JSONDict, daemons: JSONDict) -> JSONDict:
    """Each tree against the same run's bare baselines (the issue's bound: READY within
    1.5 × the bare import; steady RSS ≤ 60 MB is absolute)."""
    out: JSONDict = {}
    r, i, d = ready["summary"], imports["summary"], daemons["summary"]
    for tree in ("before", "after"):
        if r:
            for base in BARE_READY:
                out[f"ready_{tree}_over_{base}"] = _ratio(r[tree]["ready_s_median"],
                                                          r[base]["ready_s_median"])
                out[f"ready_{tree}_over_{base}_paired"] = _paired(
                    ready["samples"], tree, base, lambda x: x["ready_s"])
        if i:
            out[f"import_{tree}_over_deps_cantools"] = _ratio(
                i[f"run_{tree}"]["import_s_median"], i["deps_cantools"]["import_s_median"])
            out[f"import_{tree}_over_deps_cantools_paired"] = _paired(
                imports["samples"], f"run_{tree}", "deps_cantools", lambda x: x["import_s"])
        if d:
            out[f"steady_rss_{tree}_MB"] = _round((d[tree]["rss_steady_kB_median"] or 0) / 1024, 1)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("--before-ref", default="7f136f8", help="git ref of BEFORE (default 7f136f8)")
    p.add_argument("--before-src", help="use this checkout's src/ as BEFORE (no worktree)")
    p.add_argument("--import-trials", type=int, default=9, help="fresh interpreters per tree")
    p.add_argument("--ready-trials", type=int, default=9,
                   help="extra spawn → READY runs per tree, no frames")
    p.add_argument("--daemon-trials", type=int, default=3,
                   help="spawn → READY → steady-state runs per tree")
    p.add_argument("--steady-s", type=float, default=20.0, help="seconds of frames per run")
    p.add_argument("--rate-hz", type=float, default=2000.0, help="rate frames per second")
    p.add_argument("--cpu-trials", type=int, default=5, help="per-frame CPU rounds per tree")
    p.add_argument("--cpu-passes", type=int, default=3, help="passes per CPU child (best of)")
    p.add_argument("--cpu-rate-frames", type=int, default=50_000,
                   help="rate frames per CPU pass")
    p.add_argument("--parts", nargs="+", choices=("imports", "ready", "daemons", "cpu"),
                   default=["imports", "ready", "daemons", "cpu"],
                   help="what to measure (default all)")
    p.add_argument("--bytecode", choices=("compiled", "source"), default="compiled",
                   help="byte-compile both trees first, as a wheel install does (default), "
                   "or run them as they are")
    p.add_argument("--quick", action="store_true",
                   help="5 imports, 3 READY runs, 1 daemon run of 10 s, 3 CPU rounds")
    a = p.parse_args(argv)
    if a.quick:
        a.import_trials, a.ready_trials, a.daemon_trials, a.steady_s = 5, 3, 1, 10.0
        a.cpu_trials, a.cpu_rate_frames = 3, 20_000
    t_begin = time.monotonic()
    result: JSONDict = {"bench": "footprint", "machine": machine(),
                        "settings": {k: v for k, v in vars(a).items() if k != "quick"}}
    with before_tree(a) as before, tempfile.TemporaryDirectory(prefix="gyrotherm-fp-") as tmp, \
            compiled([before, AFTER_SRC] if a.bytecode == "compiled" else []) as pycache:
        trees = {"before": before, "after": AFTER_SRC}
        result["trees"] = {k: str(v) for k, v in trees.items()}
        result["bytecode"] = {"mode": a.bytecode, "pycache_dirs_created": len(pycache)}
        empty: JSONDict = {"summary": {}, "samples": {}}
        result["imports"] = measure_imports(trees, a.import_trials) \
            if "imports" in a.parts else empty
        result["ready"] = measure_ready(trees, a.ready_trials, Path(tmp)) \
            if "ready" in a.parts else empty
        result["daemons"] = measure_daemons(trees, a.daemon_trials, a.steady_s, a.rate_hz,
                                            Path(tmp)) if "daemons" in a.parts else empty
        result["cpu"] = measure_cpu(trees, a.cpu_trials, a.cpu_passes, a.cpu_rate_frames,
                                    Path(tmp)) if "cpu" in a.parts else empty
    result["ratios_after_over_before"] = ratios(result["imports"], result["daemons"],
                                                result["ready"])
    result["against_bare"] = ratios_to_bare(result["imports"], result["ready"],
                                            result["daemons"])
    result["elapsed_s"] = round(time.monotonic() - t_begin, 1)
    i, d = result["imports"]["summary"], result["daemons"]["summary"]
    for name in i:
        log(f"import {name:14s} {i[name]['import_s_median'] * 1e3:7.0f} ms  "
            f"RSS {i[name]['rss_kB_median'] / 1024:6.1f} MB  {i[name]['modules']:5.0f} modules  "
            f"loaded {i[name]['loaded']}")
    for name, v in result["ready"]["summary"].items():
        log(f"ready  {name:7s} READY {v['ready_s_median']:.2f} s (spawn → READY=1 only)")
    for name in d:
        log(f"daemon {name:7s} READY {d[name]['ready_s_median']:.2f} s  RSS at READY "
            f"{(d[name]['rss_at_ready_kB_median'] or 0) / 1024:.1f} MB  steady "
            f"{(d[name]['rss_steady_kB_median'] or 0) / 1024:.1f} MB  accounted "
            f"{d[name]['all_frames_accounted']}")
    for stream, v in result["cpu"]["summary"].items():
        log(f"cpu    {stream:11s} before {v['before']['us_per_frame_median']:.2f} µs/frame, "
            f"after {v['after']['us_per_frame_median']:.2f} µs/frame: after/before "
            f"{v['after_over_before']} (paired {v['after_over_before_paired']})")
    log(f"ratios after/before: {result['ratios_after_over_before']}")
    log(f"against the bare baselines: {result['against_bare']}")
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
