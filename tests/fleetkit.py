"""A simulated fleet: vehicles with IMUs whose true bias is known, logged as run files
(the simulator's chamber runs, with the identity a flight log's reader would give:
``vehicle_id``, ``device_id``, ``sensor_id``). Used by tests/cli/test_fleet_cli.py and
bench/fleet.py.

Each IMU has its own true bias (the simulator's default, its constant term moved by a
seeded amount per IMU). ``changed`` names IMUs whose constant term on ``x`` is moved
by ``change_dps`` in the logs written: a bias that really changed since a calibration
fitted to the same IMU's logs written without it.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrotherm.codecs import write_run
from gyrotherm.sim import DEFAULT_TRUE_BIAS, BiasTruth, GyroParams, chamber_runs

#: (vehicle_id, device_id, sensor_id) of the fleet's IMUs: two vehicles with two IMUs,
#: one with one (the PX4 style: device_id and sensor_id are the driver's device id).
IMUS: tuple[tuple[str, str, str], ...] = (
    ("veh-a", "2490378", "2490378"), ("veh-a", "2490386", "2490386"),
    ("veh-b", "2490378", "2490378"), ("veh-b", "2490386", "2490386"),
    ("veh-c", "2490378", "2490378"),
)


def gyro_of(index: int, *, change_dps: float = 0.0) -> GyroParams:
    """The simulated gyro of IMU ``index``: its own constant bias per axis (seeded),
    plus ``change_dps`` on x."""
    rng = np.random.default_rng(1000 + index)
    coeffs = {a: dict(c) for a, c in DEFAULT_TRUE_BIAS.items()}
    for a in coeffs:
        coeffs[a]["1"] += float(rng.uniform(-0.3, 0.3))
    coeffs["x"]["1"] += change_dps
    return GyroParams(bias=BiasTruth(coefficients=coeffs))


def write_fleet(directory: Path, *, heating_min: Sequence[float], seed: int,
                changed: Collection[int] = (), change_dps: float = 0.15,
                rate_hz: float = 2.0, hold_s: float = 900.0,
                imus: Sequence[tuple[str, str, str]] = IMUS) -> list[Path]:
    """One run file per IMU and heating time in ``directory``: names
    ``<vehicle>-<device>-<heating>.csv``; the paths, IMU by IMU."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, (vehicle, device, sensor) in enumerate(imus):
        gyro = gyro_of(i, change_dps=change_dps if i in changed else 0.0)
        for run in chamber_runs(heating_min, seed=seed * 100 + i, rate_hz=rate_hz,
                                hold_s=hold_s, gyro=gyro):
            name = f"{vehicle}-{device}-{run.name}"
            meta = {**run.metadata, "vehicle_id": vehicle, "device_id": device,
                    "sensor_id": sensor}
            paths.append(write_run(replace(run, name=name, metadata=meta),
                                   directory / f"{name}.csv"))
    return paths
