"""Run every benchmark in ``bench/``, one after the other; collect their JSON in a file.

    python bench/run_all.py                  # everything (~4-5 min on 2 cores)
    python bench/run_all.py --quick          # shorter streaming trials (~2 min)
    python bench/run_all.py --only stream_latency zenoh_baseline
    python bench/run_all.py --skip diagnose_speed --out /tmp/results.json

Each benchmark is a script ``bench/<name>.py`` that prints one JSON object on
stdout (a human summary on stderr, passed through here). The scripts are found
by listing ``bench/*.py`` (this file and ``_private.py`` modules excepted), so a
benchmark added later is run too; :data:`ARGS` gives the arguments of the known
ones (``zenoh_baseline.py`` runs its ``micro`` mode: the multi-process latency
baseline is measured inside ``stream_latency.py``, interleaved with the daemon).
They run sequentially, never in parallel (they would disturb each other), each
under ``--timeout-s``. A script that fails, times out or prints no JSON is
recorded with its exit status and the tail of its output; the exit status of
this script is then 1.

``results.json``: ``{"machine": {...}, "started_utc", "elapsed_s",
"benchmarks": {name: {"argv", "returncode", "elapsed_s", "result" | "error"}}}``,
plus ``"headline"``: the streaming figures quoted in docs/BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

BENCH_DIR = Path(__file__).resolve().parent
ORDER = ["zenoh_baseline", "stream_throughput", "stream_latency"]
"""Run first, in this order; other scripts follow alphabetically."""
ARGS: dict[str, list[str]] = {
    "zenoh_baseline": ["--mode", "micro", "--iterations", "50000"],
    "footprint": ["--import-trials", "7", "--ready-trials", "5", "--daemon-trials", "2"],
    # 6 minutes of log (an hour's library path alone takes 1.5-4 min per trial)
    "readers_fast": ["--rows", "3.6e5", "--trials", "5", "--library-trials", "2"],
}
QUICK_ARGS: dict[str, list[str]] = {
    "stream_throughput": ["--trials", "2", "--trial-s", "2", "--unpaced-frames", "100000"],
    "stream_latency": ["--trials", "3", "--trial-s", "2"],
    "footprint": ["--quick"],
}


def discover() -> list[str]:
    names = sorted(p.stem for p in BENCH_DIR.glob("*.py")
                   if p.stem != "run_all" and not p.stem.startswith("_"))  # fmt: skip
    return [n for n in ORDER if n in names] + [n for n in names if n not in ORDER]


def load_note() -> dict[str, Any]:
    one, five, fifteen = os.getloadavg()
    return {"loadavg_1_5_15": [round(one, 2), round(five, 2), round(fifteen, 2)]}


def run_one(name: str, extra: list[str], timeout_s: float) -> dict[str, Any]:
    argv = [sys.executable, str(BENCH_DIR / f"{name}.py"), *extra]
    print(f"== {name}: {' '.join(argv[1:])}", file=sys.stderr, flush=True)
    entry: dict[str, Any] = {"argv": argv[1:], "load_before": load_note()}
    start = time.monotonic()
    try:
        done = subprocess.run(argv, stdout=subprocess.PIPE, text=True, timeout=timeout_s,
                              cwd=BENCH_DIR.parent)  # fmt: skip
    except subprocess.TimeoutExpired as exc:
        entry.update(returncode=None, error=f"timeout after {timeout_s} s",
                     stdout_tail=(exc.stdout or "")[-2000:] if isinstance(exc.stdout, str)
                     else "")  # fmt: skip
    else:
        entry["returncode"] = done.returncode
        try:
            entry["result"] = json.loads(done.stdout)
        except json.JSONDecodeError:
            entry["error"] = "no JSON object on stdout"
            entry["stdout_tail"] = done.stdout[-2000:]
        if done.returncode != 0:
            entry.setdefault("error", f"exit status {done.returncode}")
    entry["elapsed_s"] = round(time.monotonic() - start, 1)
    entry["load_after"] = load_note()
    status = "ok" if "error" not in entry else f"FAILED: {entry['error']}"
    print(f"== {name}: {status} ({entry['elapsed_s']} s)", file=sys.stderr, flush=True)
    return entry


def _source_version() -> dict[str, Any]:
    """Commit and modified src/ files (read-only git), as stream_throughput reports them."""
    sys.path.insert(0, str(BENCH_DIR))
    try:
        from stream_throughput import source_version
    finally:
        sys.path.pop(0)
    return source_version()


def _get(d: Any, *path: str) -> Any:
    for key in path:
        if not isinstance(d, dict):
            return None
        d = d.get(key)
    return d


def headline(benchmarks: dict[str, Any]) -> dict[str, Any]:
    """The figures docs/BENCHMARKS.md quotes, pulled out of the streaming results."""
    thr = _get(benchmarks, "stream_throughput", "result") or {}
    lat = _get(benchmarks, "stream_latency", "result") or {}
    out: dict[str, Any] = {}
    for chain in ("bare", "core", "full"):
        s = _get(thr, "summary", chain)
        if s:
            out[f"throughput_{chain}"] = {
                "unpaced_median_rate_fps": s.get("unpaced_throughput_median_fps"),
                "unpaced_zero_loss": s.get("unpaced_zero_loss_all"),
                "paced_rate_fps": s.get("paced_rate_fps"),
                "paced_kept_up_all": s.get("paced_kept_up_all"),
                "paced_zero_loss_all": s.get("paced_zero_loss_all"),
                "paced_lag_p99_median_ms": s.get("paced_lag_p99_median_ms"),
                "cpu_us_per_rate_frame": s.get("unpaced_cpu_us_per_rate_frame_median"),
                "others_cpu_pct_median": s.get("unpaced_others_cpu_pct_median"),
            }  # fmt: skip
    if thr:
        out["throughput_ratios"] = thr.get("ratios")
        memory = thr.get("memory") or {}
        out["daemon_memory_kB"] = {c: _get(m, "daemon") for c, m in memory.items()
                                   if _get(m, "daemon")}  # fmt: skip
        out["daemon_rate_congestion_control"] = thr.get("daemon_rate_congestion_control")
        check = thr.get("congestion_control_check")
        if check:
            out["slow_subscriber_daemon_lost"] = _get(check, "daemon_block", "lost")
            out["slow_subscriber_bare_drop_lost"] = _get(check, "bare_drop", "lost")
    if lat:
        out["latency_2khz"] = {k: {kk: v.get(kk) for kk in ("p50_median_us", "p99_median_us")}
                               for k, v in (lat.get("summary") or {}).items() if k != "ratios"}
        out["latency_ratios"] = _get(lat, "summary", "ratios")
        out["latency_daemon_memory_kB"] = lat.get("memory")
    fp = _get(benchmarks, "footprint", "result") or {}
    if fp:
        imports = _get(fp, "imports", "summary") or {}
        daemons = _get(fp, "daemons", "summary") or {}
        out["footprint"] = {
            "import_s_median": {k: v.get("import_s_median") for k, v in imports.items()},
            "import_rss_kB_median": {k: v.get("rss_kB_median") for k, v in imports.items()},
            "ready_s_median": {k: v.get("ready_s_median") for k, v in daemons.items()},
            "ready_only_s_median": {k: v.get("ready_s_median") for k, v in
                                    (_get(fp, "ready", "summary") or {}).items()},
            "rss_steady_kB_median": {k: v.get("rss_steady_kB_median")
                                     for k, v in daemons.items()},
            "ratios_after_over_before": fp.get("ratios_after_over_before"),
            "against_bare": fp.get("against_bare"),
            "cpu_us_per_frame": _get(fp, "cpu", "summary"),
        }  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="run every bench/*.py, write bench/results.json")
    p.add_argument("--only", nargs="+", metavar="NAME", help="run just these benchmarks")
    p.add_argument("--skip", nargs="+", metavar="NAME", default=[], help="leave these out")
    p.add_argument("--quick", action="store_true", help="shorter streaming benchmarks")
    p.add_argument("--timeout-s", type=float, default=400.0, help="per benchmark")
    p.add_argument("--out", type=Path, default=BENCH_DIR / "results.json")
    a = p.parse_args(argv)
    names = [n for n in discover() if (not a.only or n in a.only) and n not in a.skip]
    unknown = set(a.only or ()) - set(discover())
    if unknown:
        p.error(f"no benchmark named {sorted(unknown)}; found {discover()}")
    started = time.monotonic()
    report: dict[str, Any] = {
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "nproc": len(os.sched_getaffinity(0)), "platform": platform.platform(),
                    **load_note(), "source": _source_version()},
        "started_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "quick": a.quick,
        "benchmarks": {},
    }  # fmt: skip
    for name in names:
        extra = ARGS.get(name, []) + (QUICK_ARGS.get(name, []) if a.quick else [])
        report["benchmarks"][name] = run_one(name, extra, a.timeout_s)
    report["elapsed_s"] = round(time.monotonic() - started, 1)
    report["headline"] = headline(report["benchmarks"])
    a.out.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(report["headline"], indent=1))
    print(f"wrote {a.out} ({report['elapsed_s']} s)", file=sys.stderr)
    return 0 if all("error" not in e for e in report["benchmarks"].values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
