"""Long flight logs (up to an hour at 1 kHz) in PX4 ULog, ArduPilot DataFlash and MCAP,
packed by numpy per each format's layout, not by gyrotherm's readers: the headers and
definitions come from ``ulogkit`` (the ULog specification) and ``dataflashkit``
(pymavlink's own writer code), the MCAP bag from rosbags' writer (``rosbagkit``).
Used by ``tests/readers/test_reader_memory.py`` and ``bench/readers_scale.py``.
"""

from __future__ import annotations

import struct
import tempfile
from pathlib import Path

import numpy as np

RATE_HZ = 1000.0
SUFFIX = {"ulog": ".ulg", "dataflash": ".bin", "mcap": ".mcap"}


def signal(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time (µs since boot), temperature (°C) and three rates (rad/s, shape (n, 3))."""
    from gyrotherm.analysis.synth._synth import SynthConfig, synth_run

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


