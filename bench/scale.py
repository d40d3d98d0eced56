"""How ``gyrotherm fit`` and ``gyrotherm diagnose`` grow with the length of a log.

    python bench/scale.py                          # 10⁵, 10⁶, 3.6·10⁶ rows per run
    python bench/scale.py --rows 1e5 1e6 3.6e6 1e7 --out /tmp/scale.json
    python bench/scale.py --keep-dir /tmp/scale    # reuse generated files between runs
    python bench/scale.py --rows 1e6 --skip diagnose --old-fit --repeats 3  # new vs old fit

Per row count N, three run files of N rows each are generated (seeded; the
independent generator ``gyrotherm.analysis.synth._synth`` at 1 kHz with three rate
axes, a temperature readout refreshed every 40 ms in 0.0625 °C steps: a 1-hour
1 kHz flight log has N = 3.6·10⁶ rows per IMU; below 6·10⁵ rows the run lasts the
generator's minimum of 600 s at N / 600 s Hz). Then, each as a child process:

* ``gyrotherm fit RUN_1 --no-validation`` (one log),
* ``gyrotherm fit RUN_1 RUN_2 RUN_3`` (leave-one-run-out validation),
* ``gyrotherm diagnose RUN_1 RUN_2 RUN_3 --no-simulation``,

recording wall time (s) and the child's peak resident set size (MB, from
``wait4``'s rusage: ``ru_maxrss``). The growth exponent between successive
sizes is log(ratio of cost)/log(ratio of rows). Prints one JSON object on
stdout (a table on stderr).

``--old-fit`` also times each fit job as ``fit`` ran before commit 4443ce3
(:data:`OLD_FIT`: one read of each log with the default estimator, the pooled fit;
rows ``fit1_old``, ``fit3_old``), paired with the default in the same run: each pair
runs back to back, in alternating order from one repeat to the next, and
``fit1_new_over_old`` gives the median of the per-pair ratios. ``--repeats N`` runs
every job N times (interleaved); a job's figures are then the medians, its trials
listed beside them.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

RATE_HZ = 1000.0
MIN_DURATION_S = 600.0
"""The generator's shortest run; below 6·10⁵ rows the rate is N / 600 s instead of 1 kHz."""
CHUNK_ROWS = 200_000
OLD_FIT = ("--update-period-s", "0", "--method", "pooled")
"""``gyrotherm fit`` as before commit 4443ce3: an estimator option (the default value of
any will do) skips the first pass that characterises each run's temperature readout to
choose the estimator, so each log is read once, with the default estimator; ``--method
pooled`` is the per-row pooled least squares that ``auto`` (offsets on 1-s blocks, one
offset per run, for runs that span temperature) replaced."""


def write_log(path: Path, n_rows: int, *, seed: int) -> None:
    """A three-axis 1 kHz run file of ``n_rows`` rows, written in chunks (no giant string)."""
    from gyrotherm.analysis.synth._synth import SynthConfig, synth_run

    duration_s = max(MIN_DURATION_S, n_rows / RATE_HZ)
    cfg = SynthConfig(rate_hz=n_rows / duration_s, duration_s=duration_s,
                      readout_period_s=0.04, readout_lsb_c=0.0625)
    base, _ = synth_run(cfg, seed=seed, truth_seed=7)
    axes = [base.rates_dps["x"]]
    for truth_seed in (8, 9):  # other devices' biases on the same profile
        other, _ = synth_run(cfg, seed=seed, truth_seed=truth_seed)
        axes.append(other.rates_dps["x"])
        del other
    n = min(len(base), *(len(a) for a in axes))
    cols = np.column_stack([base.time_s[:n], base.temperature_c[:n], *(a[:n] for a in axes)])
    with path.open("w", encoding="utf-8") as f:
        f.write("# gyrotherm-run: 1\n")
        f.write(f"# name: scale-{n_rows}-{seed}\n# generator: bench/scale.py seed {seed}\n")
        f.write("time_s,temperature_c,rate_x_dps,rate_y_dps,rate_z_dps\n")
        for start in range(0, n, CHUNK_ROWS):
            np.savetxt(f, cols[start:start + CHUNK_ROWS], delimiter=",", fmt="%.9g")


def measure(argv: list[str]) -> dict[str, Any]:
    """Run ``argv``; wall time and peak RSS of the child (``wait4`` rusage).

    Linux counts in a child's ``ru_maxrss`` the resident size it had before
    ``exec`` (a copy of this process): the generator therefore runs in its own
    child, so that this process stays at a few tens of MB."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    elapsed = time.perf_counter() - start
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.stderr:
        proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    out: dict[str, Any] = {"elapsed_s": round(elapsed, 2),
                           "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1),
                           "returncode": code}
    if code != 0:
        out["stderr_tail"] = err[-800:]
    return out


def _out_path(argv: list[str]) -> Path | None:
    """A ``fit`` job's calibration file (``--out``), if any."""
    return Path(argv[argv.index("--out") + 1]) if "fit" in argv and "--out" in argv else None


def _fit_method(argv: list[str]) -> str | None:
    """The method a ``fit`` job's calibration records (``auto`` resolves to one), if any."""
    if (out := _out_path(argv)) is None:
        return None
    try:
        cal = json.loads(out.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    method = cal.get("provenance", {}).get("method")
    return str(method) if method is not None else None


def _median(values: list[float]) -> float:
    return float(np.median(values))


def summary(trials: list[dict[str, Any]]) -> dict[str, Any]:
    """One job's trials: the medians (the trial itself when there is one)."""
    if len(trials) == 1:
        return trials[0]
    out: dict[str, Any] = {
        "elapsed_s": round(_median([t["elapsed_s"] for t in trials]), 2),
        "peak_rss_mb": round(_median([t["peak_rss_mb"] for t in trials]), 1),
        "returncode": next((t["returncode"] for t in trials if t["returncode"]), 0),
        "trials": len(trials),
        "elapsed_s_trials": [t["elapsed_s"] for t in trials],
        "peak_rss_mb_trials": [t["peak_rss_mb"] for t in trials]}
    if "method" in trials[-1]:
        out["method"] = trials[-1]["method"]
    tails = [t["stderr_tail"] for t in trials if "stderr_tail" in t]
    if tails:
        out["stderr_tail"] = tails[0]
    return out


def paired(jobs: dict[str, list[str]], repeats: int, *, label: str = "",
           ) -> dict[str, Any]:
    """Run ``jobs`` ``repeats`` times each, interleaved (a job ``X`` and its ``X_old``
    back to back, their order alternating between repeats); per job its
    :func:`summary`, and per pair ``X_new_over_old``: the medians of the per-pair
    ratios of time and peak RSS."""
    trials: dict[str, list[dict[str, Any]]] = {name: [] for name in jobs}
    bases = [name for name in jobs if not name.endswith("_old")]
    for k in range(repeats):
        for base in bases:
            group = [base] + ([f"{base}_old"] if f"{base}_old" in jobs else [])
            for name in group if k % 2 == 0 else group[::-1]:
                if (out := _out_path(jobs[name])) is not None:
                    out.unlink(missing_ok=True)  # the method read below is this trial's
                trial = measure(jobs[name])
                if (method := _fit_method(jobs[name])) is not None:
                    trial["method"] = method
                trials[name].append(trial)
                print(f"{label}{name:<9} #{k + 1} {trial}", file=sys.stderr, flush=True)
    out: dict[str, Any] = {name: summary(t) for name, t in trials.items()}
    for base in bases:
        if f"{base}_old" in jobs:
            pairs = list(zip(trials[base], trials[f"{base}_old"], strict=True))
            out[f"{base}_new_over_old"] = {
                key: round(_median([a[key] / b[key] for a, b in pairs if b[key] > 0]), 3)
                for key in ("elapsed_s", "peak_rss_mb")}
    return out


def growth(points: list[tuple[int, float]]) -> list[float | None]:
    """log(cost ratio) / log(rows ratio) between successive sizes."""
    out: list[float | None] = [None]
    for (n0, c0), (n1, c1) in itertools.pairwise(points):
        out.append(round(math.log(c1 / c0) / math.log(n1 / n0), 2) if c0 > 0 and c1 > 0 else None)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=float, nargs="+", default=[1e5, 1e6, 3.6e6],
                    help="rows per run file (default 1e5 1e6 3.6e6)")
    ap.add_argument("--keep-dir", help="directory for the generated run files (kept, reused)")
    ap.add_argument("--skip", nargs="*", default=[], choices=("fit1", "fit3", "diagnose"),
                    help="jobs to leave out")
    ap.add_argument("--old-fit", action="store_true",
                    help="also time each fit job as before commit 4443ce3 ("
                    f"{' '.join(OLD_FIT)}), paired in the same run: rows fit1_old, fit3_old "
                    "and the ratio new/old")
    ap.add_argument("--repeats", type=int, default=1,
                    help="run each job this many times, interleaved; medians (default 1)")
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--generate", nargs=3, metavar=("ROWS", "SEED", "PATH"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.generate:
        rows_text, seed_text, path_text = args.generate
        write_log(Path(path_text), int(rows_text), seed=int(seed_text))
        return 0
    tmp = None if args.keep_dir else tempfile.TemporaryDirectory(prefix="gyrotherm-scale-")
    work = Path(args.keep_dir or (tmp.name if tmp else "."))
    work.mkdir(parents=True, exist_ok=True)
    exe = [sys.executable, "-m", "gyrotherm", "-q"]
    rows: list[dict[str, Any]] = []
    for n_float in args.rows:
        n = int(n_float)
        files = [work / f"scale-{n}-{s}.csv" for s in (1, 2, 3)]
        for s, p in zip((1, 2, 3), files, strict=True):
            if not p.exists():  # in a child: this process stays small (see measure())
                subprocess.run([sys.executable, __file__, "--generate", str(n), str(s), str(p)],
                               check=True)
        row: dict[str, Any] = {"rows": n, "file_mb": round(files[0].stat().st_size / 1e6, 1)}
        jobs = {
            "fit1": [*exe, "fit", str(files[0]), "--no-validation", "--out", str(work / "c1.json")],
            "fit3": [*exe, "fit", *map(str, files), "--out", str(work / "c3.json")],
            "diagnose": [*exe, "diagnose", *map(str, files), "--no-simulation",
                         "--json", str(work / "d.json")],
        }
        jobs = {name: argv for name, argv in jobs.items() if name not in args.skip}
        if args.old_fit:
            jobs = {**jobs, **{f"{name}_old": [*argv, *OLD_FIT] for name, argv in jobs.items()
                               if name.startswith("fit")}}
        row.update(paired(jobs, max(1, args.repeats), label=f"{n:>10} "))
        rows.append(row)
    own_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    result: dict[str, Any] = {"bench_process_peak_rss_mb": round(own_mb, 1), "rows": rows}
    for job in ("fit1", "fit3", "diagnose", *(("fit1_old", "fit3_old") if args.old_fit else ())):
        for key in ("elapsed_s", "peak_rss_mb"):
            pts = [(r["rows"], float(r[job][key])) for r in rows if job in r]
            result[f"growth_{job}_{key}"] = growth(pts)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n", encoding="utf-8")
    if tmp:
        tmp.cleanup()
    return 0 if all(r[j].get("returncode", 0) == 0 for r in rows for j in r
                    if isinstance(r[j], dict)) else 1


if __name__ == "__main__":
    raise SystemExit(main())
