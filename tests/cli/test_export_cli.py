"""``gyrotherm export``: PX4 and ArduPilot parameters checked with the autopilots' own
correction formulas, re-implemented here from their sources:

* PX4 ``src/modules/temperature_compensation/TemperatureCompensation.cpp``
  (``calc_thermal_offsets_3D``) and ``src/lib/sensor_calibration/Gyroscope.hpp``
  (``Correct``: data − thermal_offset − offset);
* ArduPilot ``libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp``
  (``correct_sensor``, ``polynomial_eval``, TEMP_REFERENCE 35, SCALE_FACTOR 1e6).

"Our cubic" is refitted independently here with ``numpy.polyfit`` on the raw readings.
"""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import read_run
from gyrotherm.compensation import features, load_calibration, score

AXES = "xyz"
PX4_PATTERNS = (r"TC_G_ENABLE", r"TC_G[0-3]_(ID|TREF|TMIN|TMAX)", r"TC_G[0-3]_X[0-3]_[0-2]")
AP_PATTERNS = (r"INS_TCAL[1-3]_(ENABLE|TMIN|TMAX)", r"INS_TCAL[1-3]_GYR[1-3]_[XYZ]")


@dataclass(frozen=True)
class Exported:
    dir: Path
    train: list[Path]
    valid: Path
    cal: Path
    px4: Path
    ap: Path
    json: Path


@pytest.fixture(scope="module")
def exported(chamber_fit: tuple[Path, list[Path], Path, Path]) -> Exported:
    d, train, valid, cal = chamber_fit
    out = Exported(d, train, valid, cal, d / "gyro.params", d / "gyro.param", d / "export.json")
    assert main(["-q", "export", str(cal), "--px4", str(out.px4), "--ardupilot",
                 str(out.ap), "--device-id", "2359586", "--instance", "1",
                 "--cubic-target", "rows",  # the autopilots' own scripts' target, refitted here
                 "--validate", str(valid), "--json", str(out.json)]) == 0
    return out


def _reference_cubic(train: list[Path]) -> tuple[float, float, float, dict[str, np.ndarray]]:
    """TMIN, TMAX, TREF = mid-point, and per axis np.polyfit's cubic in T − TREF (rad/s)."""
    runs = [read_run(p) for p in train]
    t = np.concatenate([r.temperature_c for r in runs])
    tmin, tmax = float(t.min()), float(t.max())
    tref = 0.5 * (tmin + tmax)
    coef = {a: np.polyfit(t - tref, np.radians(np.concatenate([r.rates_dps[a] for r in runs])),
                          3) for a in AXES}
    return tmin, tmax, tref, coef


def _px4_file(path: Path) -> dict[str, tuple[str, int]]:
    """QGroundControl .params: ``vehicle component name value type``, tab-separated."""
    out = {}
    for line in path.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        veh, comp, name, value, kind = line.split("\t")
        assert (veh, comp) == ("1", "1")
        out[name] = (value, int(kind))
    return out


def _mavproxy_file(path: Path) -> dict[str, float]:
    """pymavlink mavparm.load: '#' lines skipped, ',' → ' ', two fields per line."""
    out = {}
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line or line[0] == "#":
            continue
        name, value = line.replace(",", " ").split()
        out[name] = float(value)
    return out


def test_px4_parameters_reproduce_the_cubic(exported: Exported) -> None:
    params = _px4_file(exported.px4)
    assert all(any(re.fullmatch(p, n) for p in PX4_PATTERNS) for n in params)
    assert len(params) == 1 + 4 + 12 and "TC_G1_X3_2" in params
    assert {n for n, (_, k) in params.items() if k == 6} == {"TC_G_ENABLE", "TC_G1_ID"}
    assert params["TC_G1_ID"][0] == "2359586" and params["TC_G_ENABLE"][0] == "1"
    p = {n: float(v) for n, (v, _) in params.items()}
    tmin, tmax, tref, coef = _reference_cubic(exported.train)
    assert (p["TC_G1_TMIN"], p["TC_G1_TMAX"], p["TC_G1_TREF"]) == (tmin, tmax, tref)
    valid = read_run(exported.valid)
    temps = np.concatenate([valid.temperature_c, np.linspace(tmin - 15, tmax + 15, 400)])
    for j, a in enumerate(AXES):
        raw = np.resize(np.radians(valid.rates_dps[a]), len(temps))
        corrected = []
        for data, measured in zip(raw, temps, strict=True):
            if measured > p["TC_G1_TMAX"]:  # calc_thermal_offsets_3D
                delta = p["TC_G1_TMAX"] - p["TC_G1_TREF"]
            elif measured < p["TC_G1_TMIN"]:
                delta = p["TC_G1_TMIN"] - p["TC_G1_TREF"]
            else:
                delta = measured - p["TC_G1_TREF"]
            offset = (p[f"TC_G1_X0_{j}"] + p[f"TC_G1_X1_{j}"] * delta
                      + p[f"TC_G1_X2_{j}"] * delta**2 + p[f"TC_G1_X3_{j}"] * delta**3)
            corrected.append(data - offset)  # Gyroscope::Correct, CAL offset 0
        ours = raw - np.polyval(coef[a], np.clip(temps, tmin, tmax) - tref)
        np.testing.assert_allclose(corrected, ours, rtol=0, atol=1e-9)


def test_ardupilot_parameters_reproduce_the_cubic(exported: Exported) -> None:
    p = _mavproxy_file(exported.ap)
    assert all(any(re.fullmatch(pat, n) for pat in AP_PATTERNS) for n in p)
    assert len(p) == 3 + 9 and p["INS_TCAL2_ENABLE"] == 1
    tmin, tmax, tref, coef = _reference_cubic(exported.train)
    assert (p["INS_TCAL2_TMIN"], p["INS_TCAL2_TMAX"]) == (tmin, tmax)
    valid = read_run(exported.valid)
    temps = np.concatenate([valid.temperature_c, np.linspace(tmin - 15, tmax + 15, 400)])
    for a in AXES:
        c = [p[f"INS_TCAL2_GYR{k}_{a.upper()}"] for k in (1, 2, 3)]

        def poly(tdiff: np.ndarray, c: list[float] = c) -> np.ndarray:  # polynomial_eval
            return np.asarray((c[0] + (c[1] + c[2] * tdiff) * tdiff) * tdiff * 1.0e-6)

        def reference(temperature: np.ndarray, a: str = a) -> np.ndarray:
            return np.asarray(np.polyval(coef[a], np.clip(temperature, tmin, tmax) - tref))

        raw = np.resize(np.radians(valid.rates_dps[a]), len(temps))
        for cal_temp in (tmin - 5.0, 20.0, 35.0, 47.5):
            # boot-time gyro calibration at cal_temp: offset = the rate read at rest there
            offset = reference(np.array(cal_temp))
            t = np.clip(temps, tmin, tmax)  # correct_sensor: constrain_float
            tc = float(np.clip(cal_temp, tmin, tmax))
            corrected = raw - poly(t - 35.0) + poly(np.array(tc - 35.0)) - offset
            np.testing.assert_allclose(corrected, raw - reference(temps), rtol=0, atol=1e-9)


def test_printed_errors_are_the_independently_computed_ones(
    exported: Exported, capsys: pytest.CaptureFixture[str],
) -> None:
    doc = json.loads(exported.json.read_text())
    assert doc["validation"]["in_sample"] is False
    cal = load_calibration(exported.cal)
    valid = read_run(exported.valid)
    tmin, tmax, tref, coef = _reference_cubic(exported.train)
    scores = {s.axis: s for s in score(cal, features(valid, cal.estimator))}
    for a in AXES:
        e = doc["validation"]["axes"][a]
        assert e["model_rms_dps"] == pytest.approx(scores[a].compensated.rms_dps, rel=1e-12)
        assert e["raw_rms_dps"] == pytest.approx(scores[a].raw.rms_dps, rel=1e-12)
        cubic = np.degrees(np.polyval(coef[a], np.clip(valid.temperature_c, tmin, tmax) - tref))
        resid = valid.rates_dps[a] - cubic
        assert e["cubic_rms_dps"] == pytest.approx(np.sqrt(np.mean(resid**2)), rel=1e-9)
        assert e["cubic_max_abs_dps"] == pytest.approx(np.max(np.abs(resid)), rel=1e-9)
        assert e["cubic_rms_dps"] > e["model_rms_dps"]  # the ΔT-free form costs
    capsys.readouterr()
    assert main(["-q", "export", str(exported.cal), "--ardupilot",
                 str(exported.dir / "again.param"),
                 "--validate", str(exported.valid)]) == 0
    table = capsys.readouterr().out
    for a in AXES:
        e = doc["validation"]["axes"][a]
        row = next(line for line in table.splitlines() if line.startswith(a + " "))
        assert f"{e['model_rms_dps']:.5f}" in row and f"{e['cubic_rms_dps']:.5f}" in row


def test_changed_or_missing_runs_and_missing_device_id_are_refused(
    exported: Exported, tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    runs = [shutil.copy(p, tmp_path / p.name) for p in exported.train]
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *map(str, runs), "--out", str(cal), "--no-validation"]) == 0
    ap = str(tmp_path / "a.param")
    assert main(["-q", "export", str(cal), "--px4", str(tmp_path / "p.params")]) == 2
    assert "give --device-id N" in capsys.readouterr().err
    with open(runs[0], "a", encoding="utf-8") as f:
        f.write("\n")
    assert main(["-q", "export", str(cal), "--ardupilot", ap]) == 2
    assert "changed since the fit" in capsys.readouterr().err
    Path(runs[0]).unlink()
    assert main(["-q", "export", str(cal), "--ardupilot", ap]) == 2
    assert "is missing" in capsys.readouterr().err
    # the runs given on the command line replace the provenance
    assert main(["-q", "export", str(cal), *map(str, exported.train),
                 "--ardupilot", ap]) == 0
    assert main(["-q", "export", str(cal)]) == 2
    assert "nothing to write" in capsys.readouterr().err
