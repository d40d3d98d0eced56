"""The readers' numpy fast paths against their libraries and a bare ``numpy.frombuffer``
pass, on the same 1-hour 1 kHz logs (``bench/readers_scale.py``'s), in one run.

    nice .venv/bin/python bench/readers_fast.py --keep-dir /tmp/rs     # ≈ 10 min
    nice .venv/bin/python bench/readers_fast.py --rows 3.6e5 --trials 5  # 6 minutes of log

Per format and trial, interleaved (library in the first ``--library-trials`` trials,
then fast, decode, bare, sha256), wall time (s); medians, and the median over trials of
the ratio to the ``bare`` pass run just after (the VM's speed moves within minutes):

* ``library``: the reader with ``fast=False`` (pymavlink, pyulog, rosbags decode);
* ``fast``: the reader as used (numpy fast path), the same ``list[Run]`` bit for bit;
* ``decode``: only the fast path's decoding stage (file → the gyro and temperature
  columns: ``_fast_dataflash.open_fast`` + the IMU gather, ``_fast_ulog.load``,
  ``_fast_rosbag.gather``), without what both paths share (sha256, ``make_run``);
* ``bare``: ``numpy.frombuffer`` of the mapped file with the gyro message's record
  dtype as if every record were that message, one after the other (the lower bound:
  no index, no header, no check), and the same columns converted to float64. For the
  MCAP file, whose ``Imu`` records sit inside chunks with ``Temperature`` records and
  chunk headers between, the records are taken at the ``Imu`` record's stride over the
  whole file: the same bytes touched, the same number of records;
* ``sha256``: the hash of the file every reader records (in ``library`` and ``fast``).

Prints one JSON object (medians and ratios) on stdout and a line per format on stderr.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import mmap
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from biglogkit import SUFFIX, WRITERS  # noqa: E402

DEFAULT_ROWS = 3.6e6
# the gyro message's record, as biglogkit writes it (header bytes included)
DATAFLASH = np.dtype([("h", "V3"), ("TimeUS", "<u8"), ("I", "u1"), ("GyrX", "<f4"),
                      ("GyrY", "<f4"), ("GyrZ", "<f4"), ("AccX", "<f4"), ("AccY", "<f4"),
                      ("AccZ", "<f4"), ("EG", "<u4"), ("EA", "<u4"), ("T", "<f4"),
                      ("rest", "V6")])
ULOG = np.dtype([("h", "V5"), ("timestamp", "<u8"), ("timestamp_sample", "<u8"),
                 ("device_id", "<u4"), ("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                 ("temperature", "<f4"), ("error_count", "<u4")])
# MCAP Message record (31 bytes) + CDR Imu with frame_id "imu0" (biglogkit's)
MCAP = np.dtype({"names": ["sec", "nanosec", "wx", "wy", "wz", "wcov", "ax", "ay", "az",
                           "acov"],
                 "formats": ["<i4", "<u4", "<f8", "<f8", "<f8", "<f8", "<f8", "<f8", "<f8",
                             "<f8"],
                 "offsets": [35, 39, 35 + 24 + 104, 35 + 24 + 112, 35 + 24 + 120,
                             35 + 24 + 128, 35 + 24 + 200, 35 + 24 + 208, 35 + 24 + 216,
                             35 + 24 + 224],
                 "itemsize": 31 + 4 + 24 + 296})
BARE = {"dataflash": DATAFLASH, "ulog": ULOG, "mcap": MCAP}


def bare(fmt: str, path: Path, n: int) -> Callable[[], object]:
    dtype = BARE[fmt]

    def run() -> object:
        with path.open("rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            count = min(n, len(mm) // dtype.itemsize)
            offset = len(mm) - count * dtype.itemsize if fmt != "mcap" else 0
            rec = np.frombuffer(mm, dtype=dtype, count=count, offset=offset)
            cols = [rec[name].astype(np.float64) for name in dtype.names or ()
                    if name not in ("h", "rest")]
            del rec
        return cols

    return run


def decode(fmt: str, path: Path) -> Callable[[], object]:
    def run() -> object:
        if fmt == "dataflash":
            from gyrotherm.readers._dataflash import _parts
            from gyrotherm.readers._fast_dataflash import open_fast

            log = open_fast(path)
            try:
                return _parts(path, log)
            finally:
                log.close()
        if fmt == "ulog":
            from gyrotherm.readers._fast_ulog import load
            from gyrotherm.readers._ulog import FIELDS, TOPICS

            return load(path, TOPICS, fields=FIELDS)
        from gyrotherm.readers._fast_rosbag import gather

        return gather(path, ["/imu0/data"], ["/imu0/temperature"])

    return run


def reader(fmt: str, path: Path, *, fast: bool) -> Callable[[], object]:
    def run() -> object:
        from gyrotherm.readers._dataflash import read_dataflash
        from gyrotherm.readers._rosbag import read_rosbag
        from gyrotherm.readers._ulog import read_ulog

        read = {"dataflash": read_dataflash, "ulog": read_ulog, "mcap": read_rosbag}[fmt]
        runs = read(path, fast=fast)
        if any("fast_path_fallback" in r.metadata for r in runs):
            raise SystemExit(f"{path}: the fast path fell back: {runs[0].metadata}")
        return runs

    return run


def sha(path: Path) -> Callable[[], object]:
    def run() -> object:
        h = hashlib.sha256()
        with path.open("rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()

    return run


def timed(fn: Callable[[], object]) -> float:
    t = time.perf_counter()
    out = fn()
    elapsed = time.perf_counter() - t
    del out
    return elapsed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--formats", nargs="+", choices=tuple(WRITERS), default=list(WRITERS))
    ap.add_argument("--rows", type=float, default=DEFAULT_ROWS,
                    help=f"samples per log (default {DEFAULT_ROWS:g}: one hour at 1 kHz)")
    ap.add_argument("--trials", type=int, default=9,
                    help="trials of fast, decode, bare, sha256 (default 9)")
    ap.add_argument("--library-trials", type=int, default=3,
                    help="trials of the library path (default 3; 30-70 s each an hour)")
    ap.add_argument("--keep-dir", help="directory for the generated logs (kept, reused)")
    args = ap.parse_args()
    tmp = None if args.keep_dir else tempfile.TemporaryDirectory(prefix="gyrotherm-fast-")
    work = Path(args.keep_dir or (tmp.name if tmp else "."))
    work.mkdir(parents=True, exist_ok=True)
    n = int(args.rows)
    rows: list[dict[str, Any]] = []
    for fmt in args.formats:
        path = work / f"gyro-{fmt}-{n}{SUFFIX[fmt]}"
        if not path.exists():  # the same generator (and name) as bench/readers_scale.py
            subprocess.run([sys.executable, str(HERE / "readers_scale.py"), "--generate", fmt,
                            str(n), str(path)], check=True)
        cases = {"library": reader(fmt, path, fast=False), "fast": reader(fmt, path, fast=True),
                 "decode": decode(fmt, path), "bare": bare(fmt, path, n), "sha256": sha(path)}
        times: dict[str, list[float]] = {k: [] for k in cases}
        for trial in range(max(args.trials, args.library_trials)):
            for k, fn in cases.items():
                if trial < (args.library_trials if k == "library" else args.trials):
                    times[k].append(timed(fn))
        med = {k: statistics.median(v) for k, v in times.items()}
        # the shared VM's speed moves by 2-3x within minutes: ratios of neighbours
        paired = {f"{a}_over_bare": round(statistics.median(
            x / y for x, y in zip(times[a], times["bare"], strict=False)), 2)
            for a in ("fast", "decode")}
        row = {"format": fmt, "rows": n, "file_mb": round(path.stat().st_size / 1e6, 1),
               "median_s": {k: round(v, 3) for k, v in med.items()},
               "trials_s": {k: [round(x, 3) for x in v] for k, v in times.items()},
               "library_over_fast": round(med["library"] / med["fast"], 1),
               "paired_median": paired,
               "fast_minus_sha256_over_bare": round((med["fast"] - med["sha256"])
                                                    / med["bare"], 2)}
        rows.append(row)
        print(f"{fmt:<10} {row['file_mb']:>7} MB  " + "  ".join(
            f"{k} {v:.2f}s" for k, v in med.items())
            + f"  library/fast ×{row['library_over_fast']}  paired decode/bare "
              f"×{paired['decode_over_bare']} fast/bare ×{paired['fast_over_bare']}",
            file=sys.stderr, flush=True)
    print(json.dumps({"benchmark": "readers_fast", "trials": args.trials, "rows": rows},
                     indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
