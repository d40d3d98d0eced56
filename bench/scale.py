"""How ``gyrotherm fit`` and ``gyrotherm diagnose`` grow with the length of a log.

    python bench/scale.py                          # 10⁵, 10⁶, 3.6·10⁶ rows per run
    python bench/scale.py --rows 1e5 1e6 3.6e6 1e7 --out /tmp/scale.json
    python bench/scale.py --keep-dir /tmp/scale    # reuse generated files between runs

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
        for name, argv in jobs.items():
            if name not in args.skip:
                row[name] = measure(argv)
                print(f"{n:>10} {name:<9} {row[name]}", file=sys.stderr, flush=True)
        rows.append(row)
    own_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    result: dict[str, Any] = {"bench_process_peak_rss_mb": round(own_mb, 1), "rows": rows}
    for job in ("fit1", "fit3", "diagnose"):
        for key in ("elapsed_s", "peak_rss_mb"):
            pts = [(r["rows"], float(r[job][key])) for r in rows if job in r]
            result[f"growth_{job}_{key}"] = growth(pts)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n", encoding="utf-8")
    if tmp:
        tmp.cleanup()
    return 0 if all(r[j]["returncode"] == 0 for r in rows for j in r if isinstance(r[j], dict)) \
        else 1


if __name__ == "__main__":
    raise SystemExit(main())
