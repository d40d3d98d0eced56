"""A 1-hour 1 kHz flight log in each binary format through ``gyrotherm fit``: time and memory.

    python bench/readers_scale.py                  # 3.6·10⁶ rows each (first run ≈ 10 min)
    python bench/readers_scale.py --formats ulog --rows 3.6e5  # one format, 6 minutes of log
    python bench/readers_scale.py --keep-dir /tmp/readers      # reuse the generated logs
    python bench/readers_scale.py --old-fit --keep-dir /tmp/readers  # fit now vs before 4443ce3

Per format, one log of one gyro with N samples at 1 kHz (N = 3.6·10⁶ is an hour), the
bias of the independent generator (``gyrotherm.analysis.synth._synth``, seeded) in rad/s and
its temperature readout, written with each format's own layout and not by gyrotherm:

* ``ulog``: PX4 ULog, ``sensor_gyro`` messages (the fields of PX4's ``sensor_gyro``
  uORB message) packed per the ULog specification by numpy after the header and
  definitions of ``tests/ulogkit.py``;
* ``dataflash``: ArduPilot ``IMU`` messages (``QBffffffIIfBBHH``, ``A3 95 <type>``)
  after the ``FMT`` messages pymavlink's own writer code makes (``tests/dataflashkit.py``);
* ``mcap``: a rosbag2 MCAP-storage bag written by rosbags (``sensor_msgs/msg/Imu`` at
  1 kHz, ``sensor_msgs/msg/Temperature`` at 10 Hz), then its ``.mcap`` file.

Then ``gyrotherm fit LOG --no-validation`` (rest detection on) runs as a child
process; wall time (s) and the child's peak RSS (MB, ``wait4``) are recorded, as in
``bench/scale.py``. Prints one JSON object on stdout and a line per format on stderr.
``--old-fit`` also times ``fit`` as before commit 4443ce3 (one read, the default
estimator, the pooled fit: ``scale.OLD_FIT``), paired in the same run (``fit_old``,
``fit_new_over_old``); ``--repeats N`` runs each N times, interleaved (medians).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from biglogkit import SUFFIX, WRITERS  # noqa: E402
from scale import OLD_FIT, paired  # noqa: E402

DEFAULT_ROWS = 3.6e6


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--formats", nargs="+", choices=tuple(WRITERS), default=list(WRITERS),
                    help="formats to measure (default: ulog dataflash mcap)")
    ap.add_argument("--rows", type=float,
                    help=f"samples per log (default {DEFAULT_ROWS:g}: one hour at 1 kHz)")
    ap.add_argument("--keep-dir", help="directory for the generated logs (kept, reused; "
                    "default: a temporary directory, removed)")
    ap.add_argument("--old-fit", action="store_true",
                    help=f"also time fit as before commit 4443ce3 ({' '.join(OLD_FIT)}), "
                    "paired in the same run")
    ap.add_argument("--repeats", type=int, default=1,
                    help="run each fit this many times, interleaved; medians (default 1)")
    ap.add_argument("--generate", nargs=3, metavar=("FORMAT", "ROWS", "PATH"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.generate:
        fmt, rows, path = args.generate
        WRITERS[fmt](Path(path), int(float(rows)), seed=1)
        return 0
    tmp = None if args.keep_dir else tempfile.TemporaryDirectory(prefix="gyrotherm-readers-")
    work = Path(args.keep_dir or (tmp.name if tmp else "."))
    work.mkdir(parents=True, exist_ok=True)
    results: list[dict[str, Any]] = []
    for fmt in args.formats:
        n = int(args.rows or DEFAULT_ROWS)
        log_path = work / f"gyro-{fmt}-{n}{SUFFIX[fmt]}"
        if not log_path.exists():  # in a child: this process stays small
            subprocess.run([sys.executable, __file__, "--generate", fmt, str(n), str(log_path)],
                           check=True)
        row: dict[str, Any] = {"format": fmt, "rows": n,
                               "file_mb": round(log_path.stat().st_size / 1e6, 1)}
        argv = [sys.executable, "-m", "gyrotherm", "-q", "fit", str(log_path),
                "--no-validation", "--out", str(work / f"cal-{fmt}.json")]
        jobs = {"fit": argv, **({"fit_old": [*argv, *OLD_FIT]} if args.old_fit else {})}
        row.update(paired(jobs, max(1, args.repeats), label=f"{fmt:<10} "))
        row["us_per_row"] = round(row["fit"]["elapsed_s"] / n * 1e6, 2)
        if args.old_fit:
            row["us_per_row_old"] = round(row["fit_old"]["elapsed_s"] / n * 1e6, 2)
        if math.isfinite(row["us_per_row"]):
            print(f"{fmt:<10} {n:>9} rows {row['file_mb']:>7} MB  {row['fit']}",
                  file=sys.stderr, flush=True)
        results.append(row)
    print(json.dumps({"benchmark": "readers_scale", "rows": results}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
