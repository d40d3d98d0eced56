"""Files a user would bring: logger CSVs (µs, °C, rad/s; written with the csv module)
and candump logs of a gyro with its own DBC, both carrying a known bias law."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from userdbckit import user_log

#: bias law per axis, °/s: c0 + c1·(T − 20) + c2·(T − 20)²
LAW = {"x": (0.2, 0.01, 2e-4), "y": (-0.1, -0.02, 1e-4), "z": (0.05, 0.004, 0.0)}


def bias_dps(axis: str, temp_c: np.ndarray) -> np.ndarray:
    c0, c1, c2 = LAW[axis]
    d = temp_c - 20.0
    return np.asarray(c0 + c1 * d + c2 * d * d)


def logger_csv(path: Path, *, top_c: float, seed: int, rows: int = 1200) -> Path:
    """A logger's static run: T ramps 20 °C → top_c and back, 2 Hz, µs stamps, rad/s."""
    rng = np.random.default_rng(seed)
    t_s = 5.0 + np.arange(rows) * 0.5
    temp = 20.0 + (top_c - 20.0) * np.sin(np.pi * np.arange(rows) / rows)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["timestamp", "temp", "gx", "gy", "gz"])
        rates = {a: bias_dps(a, temp) + rng.normal(0.0, 0.002, rows) for a in "xyz"}
        for i in range(rows):
            w.writerow([round(t_s[i] * 1e6), f"{temp[i]:.3f}",
                        *(repr(math.radians(rates[a][i])) for a in "xyz")])
    return path


def bus_log(tmp_path: Path, top_c: float) -> tuple[Path, Path, Path]:
    """The user's gyro on its bus: 1 Hz temperature frames ramping 25 °C → top_c,
    each followed by a rate frame carrying the bias law on the DBC's 0.01 °/s grid."""
    tmp_path.mkdir()
    temp = 25.0 + (top_c - 25.0) * np.sin(np.pi * np.arange(400) / 400)
    temp = np.round((temp + 40.0) / 0.0078125) * 0.0078125 - 40.0  # the DBC's grid
    temps = [(float(i), float(c)) for i, c in enumerate(temp)]
    rates = []
    for i, c in enumerate(temp):
        x, y, z = (float(np.round(bias_dps(a, np.array(c)) / 0.01) * 0.01) for a in "xyz")
        rates.append((i + 0.01, (x, y, z)))
    return user_log(tmp_path, temps, rates)
