"""Many flight logs through ``gyrotherm fleet`` on 1 and 2 local workers and on a Dask
local cluster of 2 worker processes: logs per minute, peak memory per worker.

    nice .venv/bin/python bench/fleet.py                       # 12 logs × 1.5·10⁵ rows, 3 rounds
    nice .venv/bin/python bench/fleet.py --logs 8 --rows 6e4 --rounds 1   # a quick look
    nice .venv/bin/python bench/fleet.py --keep-dir /tmp/fleet            # reuse the logs

The logs: half PX4 ULog, half ArduPilot DataFlash (``tests/biglogkit.py``: each
format's own layout, the independent generator's bias and temperature, seeded per log),
``--rows`` samples each over 600 s. Each configuration runs ``gyrotherm fleet LOGS
--out DIR`` (read, rest detection, T/ΔT per log on the workers; a calibration per IMU
in the main process) as a child process:

* ``jobs1``: ``--jobs 1``, serial in the command's own process;
* ``jobs2``: ``--jobs 2``, a local process pool;
* ``dask2``: ``--dask-scheduler`` of a ``distributed.LocalCluster(n_workers=2,
  threads_per_worker=1, processes=True)`` started by this script before the rounds
  (an existing cluster: its start-up is not timed);
* ``jobs2_given``: ``--jobs 2 --tau-s 120``: an estimator option given, so no first
  pass characterising each IMU's readout (``fleet`` since fded0ed reads every log
  twice without one): the ratio to ``jobs2`` is that pass's cost.

The configurations are measured round-robin (``--rounds``), so a change of the
machine's load hits all alike; medians per configuration and ratios to ``jobs1`` of
the same run. Memory: the child's peak RSS (``wait4``) for ``jobs1``; for the pools
the workers' own peak RSS, which the command prints (``workers: …``). The projection
scales the measured per-worker throughput to a fleet (assumptions in its block).
Prints one JSON object on stdout, a line per measurement on stderr.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from biglogkit import SUFFIX, WRITERS  # noqa: E402

FEATURE_BYTES_PER_ROW = 6 * 8 + 1
WORKERS_LINE = re.compile(r"workers: (\d+), peak RSS MB per worker: ([0-9., ]+)")


def _generate(work: Path, n_logs: int, rows: int) -> list[Path]:
    paths = []
    for i in range(n_logs):
        fmt = ("ulog", "dataflash")[i % 2]
        path = work / f"log{i:03d}-{rows}{SUFFIX[fmt]}"
        if not path.exists():  # in a child: this process stays small
            subprocess.run([sys.executable, __file__, "--generate", fmt, str(rows),
                            str(i + 1), str(path)], check=True)
        paths.append(path)
    return paths


def measure(argv: list[str]) -> dict[str, Any]:
    """Run ``argv``: wall time, peak RSS (``wait4``: the child and the processes it
    reaped), exit status, stderr (as ``bench/scale.py``'s, keeping stderr)."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    err = proc.stderr.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    elapsed = time.perf_counter() - start
    proc.stderr.close()
    return {"elapsed_s": round(elapsed, 2), "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1),
            "returncode": os.waitstatus_to_exitcode(status), "stderr": err}


def _once(name: str, logs: list[Path], out: Path, workers: list[str]) -> dict[str, Any]:
    argv = [sys.executable, "-m", "gyrotherm", "fleet", *map(str, logs), "--out",
            str(out / name), *workers]
    m = measure(argv)
    err = m.pop("stderr")
    if m["returncode"] != 0:
        m["stderr_tail"] = err[-800:]
    found = WORKERS_LINE.search(err)
    m["logs_per_min"] = round(len(logs) / m["elapsed_s"] * 60.0, 1)
    m["worker_peak_rss_mb"] = ([float(v) for v in found.group(2).split(",")] if found
                               else [m["peak_rss_mb"]])
    return m


def _summary(rounds: list[dict[str, Any]]) -> dict[str, Any]:
    return {"elapsed_s": [r["elapsed_s"] for r in rounds],
            "median_elapsed_s": statistics.median(r["elapsed_s"] for r in rounds),
            "median_logs_per_min": statistics.median(r["logs_per_min"] for r in rounds),
            "worker_peak_rss_mb_max": max(max(r["worker_peak_rss_mb"]) for r in rounds),
            "returncodes": sorted({r["returncode"] for r in rounds})}


def _projection(per_worker_lpm: float, rows: int, args: argparse.Namespace) -> dict[str, Any]:
    """The fleet's day of logs on ``workers`` like this machine's (assumptions listed)."""
    scale = args.fleet_log_rows / rows
    lpm = per_worker_lpm / scale  # cost linear in rows (bench/readers_scale.py: µs per row)
    minutes_one_worker = args.fleet_vehicles / lpm
    return {
        "assumptions": [
            f"{args.fleet_vehicles} vehicles × 1 log a day, each {args.fleet_log_rows:g} "
            "gyro samples (30 min at 1 kHz), half ULog half DataFlash like this bench",
            "per-log cost linear in rows (the readers and the estimator are; "
            "docs/BENCHMARKS.md, Scale)",
            "per-worker throughput = the dask2 median / 2 on this shared 2-core VM; "
            "workers scale linearly while the logs are on storage they all read at "
            "≥ 3 MB/s each and the scheduler dispatches one task per log",
            "the per-IMU fits in the main process are small (least squares on the "
            "prepared features) and not scaled",
            f"the command's process holds {FEATURE_BYTES_PER_ROW} bytes per row of every "
            "log (T, ΔT, time, 3 rates as float64, the rest mask): a day's logs are "
            "processed in groups of vehicles that fit its memory",
        ],
        "logs_per_min_per_worker": round(lpm, 2),
        "minutes_per_day_one_worker": round(minutes_one_worker, 1),
        "workers_for_one_hour": max(1, -(-int(minutes_one_worker) // 60)),
        "main_process_gb_per_100_logs": round(
            100 * args.fleet_log_rows * FEATURE_BYTES_PER_ROW / 1e9, 1),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", type=int, default=12, help="logs (default 12)")
    ap.add_argument("--rows", type=float, default=1.5e5, help="samples per log (default 1.5e5)")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of the 3 configurations")
    ap.add_argument("--keep-dir", help="directory for the logs (kept, reused; default: a "
                    "temporary directory, removed)")
    ap.add_argument("--fleet-vehicles", type=int, default=1000)
    ap.add_argument("--fleet-log-rows", type=float, default=1.8e6)
    ap.add_argument("--generate", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.generate:
        fmt, rows, seed, path = args.generate
        WRITERS[fmt](Path(path), int(float(rows)), seed=int(seed))
        return 0
    from distributed import LocalCluster

    tmp = None if args.keep_dir else tempfile.TemporaryDirectory(prefix="gyrotherm-fleet-")
    work = Path(args.keep_dir or (tmp.name if tmp else "."))
    work.mkdir(parents=True, exist_ok=True)
    rows = int(args.rows)
    logs = _generate(work, args.logs, rows)
    mb = round(sum(p.stat().st_size for p in logs) / 1e6, 1)
    results: dict[str, list[dict[str, Any]]] = {"jobs1": [], "jobs2": [], "dask2": [],
                                                "jobs2_given": []}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        configs = {"jobs1": ["--jobs", "1"], "jobs2": ["--jobs", "2"],
                   "dask2": ["--dask-scheduler", str(cluster.scheduler_address)],
                   "jobs2_given": ["--jobs", "2", "--tau-s", "120"]}
        for k in range(args.rounds):
            for name, workers in configs.items():
                m = _once(name, logs, work / f"out{k}", workers)
                results[name].append(m)
                print(f"round {k + 1} {name:<11} {m['elapsed_s']:7.2f} s "
                      f"{m['logs_per_min']:7.1f} logs/min  worker peak MB "
                      f"{m['worker_peak_rss_mb']}", file=sys.stderr, flush=True)
    summary = {name: _summary(r) for name, r in results.items()}
    base = summary["jobs1"]["median_elapsed_s"]
    for s in summary.values():
        s["speedup_vs_jobs1"] = round(base / s["median_elapsed_s"], 2)
    out = {"benchmark": "fleet", "logs": args.logs, "rows_per_log": rows, "logs_mb": mb,
           "rounds": args.rounds, "configs": summary,
           "projection": _projection(summary["dask2"]["median_logs_per_min"] / 2, rows, args)}
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
