"""Calibration files: round trip, and clear errors naming the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calkit import DELETE, broken
from gyrotherm import CalibrationError
from gyrotherm.compensation import Calibration, RunFeatures, fit, load_calibration
from gyrotherm.estimators import EstimatorConfig


@pytest.fixture(scope="module")
def calibration(paper_features: list[RunFeatures], estimator: EstimatorConfig) -> Calibration:
    return fit(paper_features[:3], "paper", estimator=estimator)


def test_round_trip(calibration: Calibration, tmp_path: Path) -> None:
    path = calibration.save(tmp_path / "cal.json")
    back = load_calibration(path)
    assert back.model == calibration.model
    assert back.scaling == calibration.scaling
    assert back.valid_range == calibration.valid_range
    assert back.estimator == calibration.estimator
    for axis in "xyz":
        np.testing.assert_array_equal(back.coefficients[axis], calibration.coefficients[axis])
    doc = json.loads(path.read_text())
    assert doc["schema"] == "gyrotherm.calibration" and doc["version"] == 1
    assert doc["units"]["bias"] == "deg/s"
    prov = doc["provenance"]
    assert [r["name"] for r in prov["runs"]] == ["heat-05min", "heat-10min", "heat-20min"]
    assert all(len(r["sha256"]) == 64 for r in prov["runs"])
    assert prov["method"] == "pooled" and prov["fit_time_utc"].endswith("Z")
    assert set(doc["coefficients_physical"]["x"]) == {"T^2", "T", "dT", "T*dT", "1"}


_broken, _DELETE = broken, DELETE


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("version", 3, r"field 'version': unsupported calibration version 3 "
         r"\(this gyrotherm reads versions 1, 2\)"),
        ("version", 2, r"field 'units.time': expected 's', got None"),
        ("schema", "px4", r"field 'schema': expected 'gyrotherm.calibration'"),
        ("scaling.t_ref_c", _DELETE, r"missing field 'scaling.t_ref_c'"),
        ("scaling.t_scale_c", "wide", r"field 'scaling.t_scale_c': expected int/float"),
        ("coefficients.x", [1.0, 2.0], r"coefficients.x: expected 5 finite numbers"),
        ("coefficients.x", [0.1, 0.2, "a", 0.4, 0.5],
         r"field 'coefficients.x\[2\]': expected a number, got 'a'"),
        ("coefficients_physical.x.T^2", 123.0,
         r"field 'coefficients_physical.x.T\^2' = 123.0 disagrees with 'coefficients.x'"),
        ("coefficients_physical.y", {"T": 1.0},
         r"field 'coefficients_physical.y': expected terms"),
        ("model.name", "quartic", r"field 'model.name': unknown model 'quartic'"),
        ("model.terms", ["T", "1"], r"field 'model.terms'"),
        ("units.rate", "rad/s", r"field 'units.rate': expected 'deg/s'"),
        ("range", _DELETE, r"missing field 'range.t_min_c'"),
        ("estimator.tau_s", -1.0, r"estimator.tau_s = -1.0 is outside"),
        ("estimator.colour", 1, r"unknown field\(s\) \['colour'\]"),
        ("provenance", _DELETE, r"missing field 'provenance'"),
    ],
)
def test_bad_files_name_the_field(
    calibration: Calibration, tmp_path: Path, path: str, value: object, message: str
) -> None:
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(_broken(calibration.to_dict(), path, value)))
    with pytest.raises(CalibrationError, match=message) as info:
        load_calibration(p)
    assert str(p) in str(info.value)


def test_not_json_and_missing_file(tmp_path: Path) -> None:
    p = tmp_path / "cal.json"
    p.write_text('{"schema": "gyrotherm.calibration",\n  "version": }')
    with pytest.raises(CalibrationError, match=r"line 2: not valid JSON"):
        load_calibration(p)
    with pytest.raises(CalibrationError, match="cannot read calibration file"):
        load_calibration(tmp_path / "absent.json")
    p.write_text("[1, 2]")
    with pytest.raises(CalibrationError, match="expected a JSON object"):
        load_calibration(p)


def test_absurd_json_is_a_calibration_error(calibration: Calibration, tmp_path: Path) -> None:
    p = tmp_path / "bad.json"
    doc = calibration.to_dict()
    doc["coefficients"]["x"][0] = 10**400  # valid JSON, not a float
    p.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match=r"field 'coefficients.x\[0\]': an integer of "
                       r"401 digits \(at most 19 accepted\)"):
        load_calibration(p)
    p.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(CalibrationError, match=f"{p}: JSON nested 100000 deep"):
        load_calibration(p)
    doc = calibration.to_dict()
    doc["model"]["terms"] = ["T^x", "T", "dT", "T*dT", "1"]
    p.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match=r"bad.json: field 'model.terms'"):
        load_calibration(p)


def test_read_calibration_ids_the_bytes_parsed(calibration: Calibration, tmp_path: Path) -> None:
    import hashlib

    from gyrotherm.compensation import read_calibration

    p = calibration.save(tmp_path / "cal.json")
    cal, cid = read_calibration(p)
    assert cid == hashlib.sha256(p.read_bytes()).hexdigest()[:16]
    assert cal.coefficients == calibration.coefficients


def test_save_where_it_cannot_write_names_the_path(
    calibration: Calibration, tmp_path: Path
) -> None:
    target = tmp_path / "missing-dir" / "imu0.json"
    with pytest.raises(CalibrationError, match=r"missing-dir/imu0\.json: cannot write") as info:
        calibration.save(target)
    assert isinstance(info.value.__cause__, FileNotFoundError)
    assert not list(tmp_path.rglob("*.tmp"))  # nothing left behind


def test_base_series_in_blocks_equals_base_bias(
    calibration: Calibration, monkeypatch: pytest.MonkeyPatch
) -> None:
    """base_series evaluates a long log a block at a time: every row equals the
    scalar base_bias (math.fsum of the terms), whatever the block size."""
    from gyrotherm.compensation import _calibration

    rng = np.random.default_rng(2)
    t = rng.uniform(-20, 50, 1000)
    d = rng.normal(0, 2, 1000)
    whole = calibration.base_series("x", t, d)
    monkeypatch.setattr(_calibration, "SERIES_BLOCK_ROWS", 7)
    blocked = calibration.base_series("x", t, d)
    np.testing.assert_array_equal(blocked, whole)
    scalar = np.array([calibration.base_bias("x", float(a), float(b))
                       for a, b in zip(t, d, strict=True)])
    np.testing.assert_allclose(whole, scalar, rtol=1e-12, atol=1e-15)
