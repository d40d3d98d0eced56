"""A 1-hour 1 kHz flight log in each binary format through ``gyrotherm fit``: time and memory.

    python bench/readers_scale.py                  # 3.6·10⁶ rows each (first run ≈ 10 min)
    python bench/readers_scale.py --formats ulog --rows 3.6e5  # one format, 6 minutes of log
    python bench/readers_scale.py --keep-dir /tmp/readers      # reuse the generated logs

Per format, one log of one gyro with N samples at 1 kHz (N = 3.6·10⁶ is an hour), the
bias of the independent generator (``gyrotherm.analysis._synth``, seeded) in rad/s and
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
``bench/scale.py``. Prints one JSON object on stdout, a table on stderr.
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

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from scale import measure  # noqa: E402

RATE_HZ = 1000.0
DEFAULT_ROWS = 3.6e6
SUFFIX = {"ulog": ".ulg", "dataflash": ".bin", "mcap": ".mcap"}


def signal(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time (µs since boot), temperature (°C) and three rates (rad/s, shape (n, 3))."""
    from gyrotherm.analysis._synth import SynthConfig, synth_run

    duration_s = max(600.0, n / RATE_HZ)
    cfg = SynthConfig(rate_hz=n / duration_s, duration_s=duration_s,
                      readout_period_s=0.04, readout_lsb_c=0.0625)
    run, _ = synth_run(cfg, seed=seed, truth_seed=7)
    m = min(n, len(run))
    t_us = (1_000_000 + np.round(run.time_s[:m] * 1e6)).astype(np.uint64)
    rates = np.radians(np.column_stack([run.rates_dps["x"][:m]] * 3))
    rates[:, 1] *= -0.5
    rates[:, 2] *= 0.25
    return t_us, run.temperature_c[:m].copy(), rates


def write_ulog(path: Path, n: int, seed: int) -> None:
    from ulogkit import GYRO0_DEVICE_ID, _msg, header_and_definitions

    t_us, temp, rates = signal(n, seed)
    # D message: uint16 size, 'D', uint16 msg_id, then GYRO_FIELDS packed
    dt = np.dtype([("size", "<u2"), ("kind", "u1"), ("msg_id", "<u2"), ("timestamp", "<u8"),
                   ("timestamp_sample", "<u8"), ("device_id", "<u4"), ("x", "<f4"),
                   ("y", "<f4"), ("z", "<f4"), ("temperature", "<f4"),
                   ("error_count", "<u4")])
    rec = np.zeros(len(t_us), dtype=dt)
    rec["size"] = dt.itemsize - 3
    rec["kind"] = ord("D")
    rec["timestamp"] = t_us + 500
    rec["timestamp_sample"] = t_us
    rec["device_id"] = GYRO0_DEVICE_ID
    rec["x"], rec["y"], rec["z"] = rates.T
    rec["temperature"] = temp
    import struct

    head = header_and_definitions() + _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    with path.open("wb") as f:
        f.write(head)
        f.write(rec.tobytes())


def write_dataflash(path: Path, n: int, seed: int) -> None:
    from dataflashkit import IMU, log

    t_us, temp, rates = signal(n, seed)
    dt = np.dtype([("h1", "u1"), ("h2", "u1"), ("type", "u1"), ("TimeUS", "<u8"),
                   ("I", "u1"), ("GyrX", "<f4"), ("GyrY", "<f4"), ("GyrZ", "<f4"),
                   ("AccX", "<f4"), ("AccY", "<f4"), ("AccZ", "<f4"), ("EG", "<u4"),
                   ("EA", "<u4"), ("T", "<f4"), ("GH", "u1"), ("AH", "u1"),
                   ("GHz", "<u2"), ("AHz", "<u2")])
    rec = np.zeros(len(t_us), dtype=dt)
    rec["h1"], rec["h2"], rec["type"] = 0xA3, 0x95, IMU.type
    rec["TimeUS"] = t_us
    rec["GyrX"], rec["GyrY"], rec["GyrZ"] = rates.T
    rec["AccZ"] = -9.80665
    rec["T"] = temp
    rec["GH"] = rec["AH"] = 1
    rec["GHz"] = rec["AHz"] = 1000
    with path.open("wb") as f:
        f.write(log([IMU], []))
        f.write(rec.tobytes())


def write_mcap(path: Path, n: int, seed: int) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer

    from rosbagkit import IMU, T0_NS, TEMPERATURE, imu_msg, temperature_msg

    t_us, temp, rates = signal(n, seed)
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            from rosbagkit import STORE

            imu = w.add_connection("/imu0/data", IMU, typestore=STORE)
            tc = w.add_connection("/imu0/temperature", TEMPERATURE, typestore=STORE)
            for k in range(len(t_us)):
                ns = T0_NS + int(t_us[k]) * 1000
                if k % 100 == 0:
                    w.write(tc, ns, temperature_msg(ns, "imu0", float(temp[k])))
                w.write(imu, ns, imu_msg(ns, "imu0", tuple(map(float, rates[k])),
                                         (0.0, 0.0, 9.80665)))
        (next(bag.glob("*.mcap"))).replace(path)


WRITERS = {"ulog": write_ulog, "dataflash": write_dataflash, "mcap": write_mcap}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--formats", nargs="+", choices=tuple(WRITERS), default=list(WRITERS),
                    help="formats to measure (default: all three)")
    ap.add_argument("--rows", type=float,
                    help="samples per log (default 3.6e6: one hour at 1 kHz)")
    ap.add_argument("--keep-dir", help="directory for the generated logs (kept, reused)")
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
        row["fit"] = measure([sys.executable, "-m", "gyrotherm", "-q", "fit", str(log_path),
                              "--no-validation", "--out", str(work / f"cal-{fmt}.json")])
        row["us_per_row"] = round(row["fit"]["elapsed_s"] / n * 1e6, 2)
        if math.isfinite(row["us_per_row"]):
            print(f"{fmt:<10} {n:>9} rows {row['file_mb']:>7} MB  {row['fit']}",
                  file=sys.stderr, flush=True)
        results.append(row)
    print(json.dumps({"benchmark": "readers_scale", "rows": results}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
