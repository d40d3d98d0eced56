"""Three IMUs at 1 kHz: one `gyrotherm run` for all three vs three `run --imu` processes.

The question of project issue 21, item 1: does a vehicle's daemon serve its IMUs in one
process (one bus reader, one Zenoh session, frames routed by id) or one process per IMU
(a systemd template unit, ``gyrotherm@imu0.service`` …)? Same frames, same host, same run.

Setup per trial: three simulated gyros (``sim._gyros``: own physics, seeds and CAN ids)
at ``--rate-hz`` (1000) for ``--duration-s``, paced in real time by this process onto a
SocketcandServer on 127.0.0.1 (the bus: this machine has no SocketCAN); a subscriber
process takes every rate message of the three sensors. Paths, alternated round by round:

* ``one``: ``gyrotherm run --config multi.toml`` (three [[imu]] tables, consistency on);
* ``three``: ``gyrotherm run --config multi.toml --imu imuK`` for K = 0, 1, 2, each with
  its own Zenoh port (the tables' ``listen``); each reads the whole bus (socketcand
  sends every frame to every client) and counts the other IMUs' frames as unknown ids.

Measured over the play after ``--warmup-s``: CPU of the daemon process(es)
(utime + stime from /proc, summed, as % of one core), VmRSS at the end (summed),
and per rate message the *lag* = subscriber arrival (time.time()) − the frame's
scheduled send time (the frame's sensor time mapped to the wall clock of the play),
p50 and p99 over the three sensors. Prints one JSON object on stdout; medians over the
rounds and the ratios three/one from the same rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

BENCH_DIR = Path(__file__).resolve().parent
SENSORS = ("imu0", "imu1", "imu2")
JSONDict = dict[str, Any]


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_kb(pid: int) -> int:
    with open(f"/proc/{pid}/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def subscriber_main(endpoints: list[str], out: str) -> int:
    """Child: subscribe to every sensor's rate; on stdin EOF write arrivals to ``out``."""
    from gyrotherm.client import Subscriber

    rows: list[tuple[float, float]] = []
    subs = []
    for i, name in enumerate(SENSORS):
        ep = endpoints[i % len(endpoints)]

        def on_rate(m: Any) -> None:
            rows.append((time.time(), m.sensor_time_s))

        subs.append(Subscriber("bench", name, connect=[ep], on_rate=on_rate))
    print("subscribed", flush=True)
    sys.stdin.read()
    for s in subs:
        s.close()
    Path(out).write_text(json.dumps(rows))
    return 0


def _config(tmp: Path, bus_port: int, zports: list[int]) -> Path:
    tables = "\n".join(
        f'[[imu]]\nsensor = "{s}"\nlisten = ["tcp/127.0.0.1:{zports[k + 1]}"]\n'
        f"signals = {{ rate_frame_id = {0x120 + 2 * k}, temperature_frame_id = {0x121 + 2 * k} }}\n"
        for k, s in enumerate(SENSORS))
    path = tmp / "multi.toml"
    path.write_text(f"""vehicle = "bench"
[can]
interface = "socketcand"
host = "127.0.0.1"
port = {bus_port}
channel = "vcan0"
[zenoh]
listen = ["tcp/127.0.0.1:{zports[0]}"]
{tables}""")
    return path


def trial(path: str, frames: list[Any], a: argparse.Namespace, tmp: Path) -> JSONDict:
    from gyrotherm.sim import SocketcandServer
    from gyrotherm.sim._stream import play

    sys.path.insert(0, str(BENCH_DIR.parent / "tests"))
    from streamkit import free_port

    zports = [free_port() for _ in range(4)]
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        cfg = _config(tmp, server.port, zports)
        argvs = ([["--config", str(cfg)]] if path == "one" else
                 [["--config", str(cfg), "--imu", s] for s in SENSORS])
        procs = [subprocess.Popen([sys.executable, "-m", "gyrotherm", "-q", "run", *argv],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                 for argv in argvs]
        eps = ([f"tcp/127.0.0.1:{zports[0]}"] if path == "one" else
               [f"tcp/127.0.0.1:{p}" for p in zports[1:]])
        out = tmp / f"arrivals-{path}.json"
        sub = subprocess.Popen([sys.executable, __file__, "--subscriber", str(out), *eps],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        try:
            assert server.wait_for_clients(len(procs), 30.0), "daemons did not connect"
            assert sub.stdout is not None and sub.stdout.readline().strip() == "subscribed"
            time.sleep(2.0)  # bench only: let the subscribers' declarations reach the daemons
            play(frames[: int(len(frames) * a.warmup_s / a.duration_s)], server, speed=1.0,
                 clock=time.time)
            cpu0, w0 = sum(_cpu_s(p.pid) for p in procs), time.time()
            play(frames[int(len(frames) * a.warmup_s / a.duration_s):], server, speed=1.0,
                 clock=time.time)
            cpu1, w1 = sum(_cpu_s(p.pid) for p in procs), time.time()
            rss = sum(_rss_kb(p.pid) for p in procs)
            server.flush(10.0)
            time.sleep(0.5)  # bench only: the last messages in flight
        finally:
            for p in procs:
                p.terminate()
            for p in procs:
                p.wait(20)
            if sub.stdin:
                sub.stdin.close()
            sub.wait(20)
    rows = np.array(json.loads(out.read_text()))
    # the second play restarts the schedule: map its frames with its own start
    t_split = frames[int(len(frames) * a.warmup_s / a.duration_s)].timestamp
    measured = rows[rows[:, 1] >= t_split]
    # scheduled send time of the second play ≈ w0 + (ts − t_split)
    lag_ms = (measured[:, 0] - (w0 + measured[:, 1] - t_split)) * 1e3
    return {"path": path, "processes": len(procs), "cpu_pct": 100 * (cpu1 - cpu0) / (w1 - w0),
            "rss_MB": rss / 1024, "messages": len(measured),
            "lag_p50_ms": float(np.percentile(lag_ms, 50)),
            "lag_p99_ms": float(np.percentile(lag_ms, 99))}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--subscriber", nargs="+", help=argparse.SUPPRESS)
    p.add_argument("--rate-hz", type=float, default=1000.0)
    p.add_argument("--duration-s", type=float, default=20.0)
    p.add_argument("--warmup-s", type=float, default=5.0)
    p.add_argument("--trials", type=int, default=3)
    a = p.parse_args(argv)
    if a.subscriber:
        return subscriber_main(a.subscriber[1:], a.subscriber[0])
    from gyrotherm.sim import ChamberProfile, simulate
    from gyrotherm.sim._gyros import gyro_params, several_gyros

    runs = [simulate(ChamberProfile.from_pairs([(0.0, 20.0), (a.duration_s, 25.0)]),
                     name=f"g{k}", gyro=gyro_params(k), rate_hz=a.rate_hz, seed=k)
            for k in range(3)]
    frames = list(several_gyros(runs))
    results: list[JSONDict] = []
    with tempfile.TemporaryDirectory() as d:
        for r in range(a.trials):
            for path in ("one", "three") if r % 2 == 0 else ("three", "one"):
                res = trial(path, frames, a, Path(d))
                print(json.dumps(res), file=sys.stderr, flush=True)
                results.append(res)
    summary: JSONDict = {"rate_hz": a.rate_hz, "imus": 3, "trials": results}
    for path in ("one", "three"):
        mine = [x for x in results if x["path"] == path]
        summary[path] = {k: round(float(np.median([x[k] for x in mine])), 2)
                         for k in ("cpu_pct", "rss_MB", "lag_p50_ms", "lag_p99_ms", "messages")}
    pairs = [(x, y) for x in results if x["path"] == "three" for y in results
             if y["path"] == "one" and results.index(y) // 2 == results.index(x) // 2]
    summary["ratio_three_over_one"] = {
        k: round(float(np.median([x[k] / y[k] for x, y in pairs])), 2)
        for k in ("cpu_pct", "rss_MB", "lag_p50_ms", "lag_p99_ms")}
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
