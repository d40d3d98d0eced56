"""A PX4 user's path end to end: ULog flight logs with two IMUs and motion →
``gyrotherm fit`` (one calibration per device id, motion masked) → ``gyrotherm
evaluate`` and ``gyrotherm export --px4`` on the same logs.

The logs are written byte-exact from the ULog specification (tests/ulogkit.py, not
gyrotherm's reader) from simulated chamber runs of two gyros with different true
biases, turned at known times; the truth is the simulator's.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import Run
from gyrotherm.sim import BiasTruth, GyroParams, chamber_runs
from motionkit import truth_rms, with_rotations
from ulogkit import ACCEL_FIELDS, GYRO_FIELDS, _msg, _pack, header_and_definitions

DEVICE_IDS = {"a": 263178, "b": 2424842}
TRUTH_B = {  # device b's true bias (device a: the simulator default)
    "x": {"T^2": -6.0e-5, "T": 0.012, "dT": -0.040, "T*dT": 2.0e-4, "1": -0.15},
    "y": {"T^2": 9.0e-5, "T": -0.008, "dT": 0.025, "T*dT": -3.0e-4, "1": 0.25},
    "z": {"T^2": -4.0e-5, "T": 0.005, "dT": 0.020, "T*dT": 1.0e-4, "1": -0.05},
}
TURNS_S = ((700.0, 730.0), (1400.0, 1460.0))


def _ulog(runs: dict[str, Run]) -> bytes:
    """sensor_gyro and sensor_accel, one instance per device (rad/s, m/s², µs)."""
    out = header_and_definitions()
    for inst, _ in enumerate(runs):
        out += _msg(b"A", struct.pack("<BH", inst, 2 * inst) + b"sensor_gyro")
        out += _msg(b"A", struct.pack("<BH", inst, 2 * inst + 1) + b"sensor_accel")
    for inst, (dev, run) in enumerate(runs.items()):
        us = np.round(run.time_s * 1e6).astype(np.int64) + 1_000_000
        w = {a: np.radians(run.rates_dps[a]) for a in "xyz"}
        acc = [run.extra[f"accel_{a}_mps2"] for a in "xyz"]
        for i in range(len(run)):
            out += _msg(b"D", struct.pack("<H", 2 * inst) + _pack(GYRO_FIELDS, [
                us[i] + 50, us[i], DEVICE_IDS[dev], w["x"][i], w["y"][i], w["z"][i],
                run.temperature_c[i], 0]))
            out += _msg(b"D", struct.pack("<H", 2 * inst + 1) + _pack(ACCEL_FIELDS, [
                us[i] + 60, us[i], DEVICE_IDS[dev] + 1, acc[0][i], acc[1][i], acc[2][i],
                run.temperature_c[i], 0]))
    return out


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Path], dict[str, list[Run]]]:
    """Two ULogs (heating 10 and 40 min), each with both IMUs; the simulated runs."""
    out = tmp_path_factory.mktemp("ulog")
    gyros = {"a": GyroParams(), "b": GyroParams(bias=BiasTruth(coefficients=TRUTH_B))}
    sims = {dev: [with_rotations(r, TURNS_S, accel=True, seed=7 + k)
                  for k, r in enumerate(chamber_runs([10, 40], seed=20 + j, rate_hz=2.0,
                                                     hold_s=1200.0, gyro=g))]
            for j, (dev, g) in enumerate(gyros.items())}
    paths = []
    for k in range(2):
        p = out / f"flight{k}.ulg"
        p.write_bytes(_ulog({dev: sims[dev][k] for dev in gyros}))
        paths.append(p)
    return paths, sims


def _truth_rms(cal_path: Path, runs: list[Run]) -> float:
    return truth_rms(cal_path, runs, TURNS_S)


def test_two_imus_in_ulogs_fit_evaluate_export(
    flights: tuple[list[Path], dict[str, list[Run]]], tmp_path: Path,
) -> None:
    paths, sims = flights
    cals = tmp_path / "cals"
    summary = tmp_path / "fit.json"
    assert main(["-q", "fit", *map(str, paths), "--out", str(cals), "--no-validation",
                 "--json", str(summary)]) == 0
    doc = json.loads(summary.read_text())
    devices = {c["device"]: Path(c["path"]) for c in doc["calibrations"]}
    assert sorted(devices) == sorted(str(i) for i in DEVICE_IDS.values())
    for run in doc["rest"]["runs"]:  # both turns of every run found, little else
        assert len(run["segments"]) == len(TURNS_S)
        assert 90.0 < run["excluded_s"] < 90.0 + 4 * len(TURNS_S) * 2.2
    own = {dev: _truth_rms(devices[str(DEVICE_IDS[dev])], sims[dev]) for dev in DEVICE_IDS}
    cross = _truth_rms(devices[str(DEVICE_IDS["a"])], sims["b"])
    assert max(own.values()) < 0.02, own
    assert cross > 10 * max(own.values())

    scores = tmp_path / "eval.json"
    cal_a = devices[str(DEVICE_IDS["a"])]
    assert main(["-q", "evaluate", str(cal_a), *map(str, paths), "--json", str(scores)]) == 0
    by_run: dict[str, list[float]] = {}
    for s in json.loads(scores.read_text())["scores"]:
        by_run.setdefault(s["run"], []).append(s["compensated"]["rms_dps"])
    # only the calibration's IMU is scored: the other IMU of each log is left out
    assert sorted(by_run) == ["flight0:sensor_gyro0", "flight1:sensor_gyro0"]

    params = tmp_path / "px4.params"
    assert main(["-q", "export", str(cal_a), "--px4", str(params), "--json",
                 str(tmp_path / "export.json")]) == 0
    lines = [ln.split("\t") for ln in params.read_text().splitlines()
             if ln and not ln.startswith("#")]
    values = {ln[2]: ln[3] for ln in lines}
    assert values["TC_G0_ID"] == str(DEVICE_IDS["a"])
    exported = json.loads((tmp_path / "export.json").read_text())
    assert len(exported["fit_runs"]) == 2  # the device-a run of each log, re-read by name
