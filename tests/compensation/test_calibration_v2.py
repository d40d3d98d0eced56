"""Calibration files version 2 (effects) and the per-axis compensator: round trips,
v1 unchanged, parity with the fitted model and with the diagnosis' vectorised
columns, state persistence, and errors naming the file and field."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from calkit import DELETE, broken
from gyrotherm import CalibrationError
from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel, design
from gyrotherm.analysis._to_calibration import calibration_from_models
from gyrotherm.compensation import (
    Calibration,
    Compensator,
    RunFeatures,
    Scaling,
    ValidRange,
    fit,
    load_calibration,
)
from gyrotherm.compensation._effects import EffectFlags, Effects, Hysteresis, Warmup
from gyrotherm.estimators import EstimatorConfig

SCALING = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=8.0)
EFFECTS = {"thermal_lag": 75.0, "hysteresis": 0.35, "warmup": 400.0, "cubic": 0.0,
           "gradient_quadratic": 0.0, "drift": 0.0}
COLUMNS = (*BASE_COLUMNS, "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift")
COEFFICIENTS = (0.02, -0.05, 0.03, 0.004, 0.012, -0.08, 0.006, -0.002, 0.003)


def chamber_like(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time (1 s), T and ΔT of hold → ramp up → hold → ramp down with noise (seeded)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=np.float64)
    knots = np.array([0.0, 0.15, 0.45, 0.6, 0.9, 1.0]) * t[-1]
    temp = np.interp(t, knots, [-20.0, -20.0, 50.0, 50.0, 10.0, 10.0])
    temp = temp + np.cumsum(rng.normal(0.0, 0.02, n)) + rng.normal(0.0, 0.01, n)
    return t, temp, 120.0 * np.gradient(temp, t)


def _models() -> dict[str, ExtendedModel]:
    x = ExtendedModel(SCALING, EFFECTS, COLUMNS, COEFFICIENTS, intercept_dps=0.7)
    y = ExtendedModel(SCALING, {}, BASE_COLUMNS, (-0.01, 0.04, 0.02, -0.003), intercept_dps=-0.2)
    return {"x": x, "y": y}


@pytest.fixture(scope="module")
def v2() -> Calibration:
    return calibration_from_models(
        _models(), estimator=EstimatorConfig(), t_on_max_s=7200.0,
        valid_range=ValidRange(-60.0, 90.0, -500.0, 500.0), provenance={"method": "by hand"})


@pytest.fixture(scope="module")
def v1(paper_features: list[RunFeatures], estimator: EstimatorConfig) -> Calibration:
    return fit(paper_features[:3], "paper", estimator=estimator)


def test_v1_files_are_unchanged(v1: Calibration, tmp_path: Path) -> None:
    doc = v1.to_dict()
    assert doc["version"] == 1 and "effects" not in doc and "runtime_state" not in doc
    assert "time" not in doc["units"]
    path = v1.save(tmp_path / "v1.json")
    back = load_calibration(path)
    assert back.effects == {} and back.version == 1
    assert back.to_dict() == json.loads(path.read_text())
    # its compensator is the paper polynomial: bit-exact with bias_at, clamping included
    comp = back.compensator()
    r = back.valid_range
    for k, (t, d) in enumerate([(20.0, 0.5), (r.t_max_c + 30.0, 0.0), (r.t_min_c, r.dt_min_c - 5),
                                (-3.25, r.dt_max_c)]):
        got, want = comp.step(float(k), t, d), back.bias_at(t, d)
        assert got.bias_dps == want.bias_dps
        assert (got.t_clamped, got.dt_clamped) == (want.t_clamped, want.dt_clamped)
        assert got.flags & ~(EffectFlags.T_CLAMPED | EffectFlags.DT_CLAMPED) == 0


def test_v1_series_equals_the_vectorised_polynomial(v1: Calibration,
                                                    paper_features: list[RunFeatures]) -> None:
    f = paper_features[4]
    out = v1.compensator().series(f.time_s, f.temperature_c, f.delta_t_c)
    for axis in v1.axes:
        bias, clamped = v1.bias_series(axis, f.temperature_c, f.delta_t_c)
        assert np.max(np.abs(out.bias_dps[axis] - bias)) < 1e-12
        assert np.array_equal(out.clamped(axis), clamped)


def test_v2_round_trip(v2: Calibration, tmp_path: Path) -> None:
    doc = v2.to_dict()
    assert doc["version"] == 2 and doc["units"]["time"] == "s"
    assert doc["effects"]["y"] == {}
    assert doc["effects"]["x"]["hysteresis"] == {"amplitude_dps": 0.012, "transition_c": 0.35}
    assert doc["effects"]["x"]["cubic"]["t_ref_c"] == SCALING.t_ref_c
    assert doc["effects"]["x"]["drift"] == {"slope_dps_per_h": 0.003, "t_on_max_s": 7200.0}
    assert doc["runtime_state"]["version"] == 1 and "hysteresis_h" in doc["runtime_state"]["fields"]
    assert doc["model"]["terms"] == ["T^2", "T", "dT", "T*dT", "1"]
    assert doc["coefficients"]["x"] == [*COEFFICIENTS[:4], 0.7]
    back = load_calibration(v2.save(tmp_path / "v2.json"))
    assert back.effects == v2.effects and back.coefficients == v2.coefficients
    assert back.to_dict() == doc
    with pytest.raises(CalibrationError, match=r"bias_at cannot evaluate them.*compensator"):
        back.bias_at(20.0, 0.0)


def test_v2_compensator_equals_the_model_and_the_diagnosis_columns(
    v2: Calibration, tmp_path: Path
) -> None:
    """The file's compensator against ExtendedModel.bias (the same kernel, via the
    converter and a file round trip) and against the diagnosis' vectorised design
    columns (independent); stopped, saved as JSON and resumed mid-run."""
    t, temp, dtemp = chamber_like(5000, 5)
    cal = load_calibration(v2.save(tmp_path / "v2.json"))
    models = _models()
    first = cal.compensator()
    a = first.series(t[:2222], temp[:2222], dtemp[:2222])
    saved = json.loads(json.dumps(first.state_dict()))
    b = Compensator.load_state(cal, saved).series(t[2222:], temp[2222:], dtemp[2222:])
    for axis, model in models.items():
        got = np.r_[a.bias_dps[axis], b.bias_dps[axis]]
        assert np.max(np.abs(got - model.bias(t, temp, dtemp))) < 1e-9
        names, x = design(t, temp, dtemp, SCALING, model.effects, step_s=1.0)
        want = x @ np.array(model.coefficients) + model.intercept_dps
        assert names == model.columns and np.max(np.abs(got - want)) < 1e-9
        assert not a.flags[axis].any() and not b.flags[axis].any()
    assert np.ptp(a.bias_dps["x"] - models["x"].bias(t[:2222], temp[:2222], dtemp[:2222])) \
        < 1e-9
    # one step at a time gives the same as the series
    comp = cal.compensator()
    steps = [comp.step(*row).bias_dps["x"] for row in zip(t[:300], temp[:300], dtemp[:300],
                                                          strict=True)]
    assert np.max(np.abs(np.array(steps) - a.bias_dps["x"][:300])) < 1e-12


def test_compensator_flags_and_time_before_power_on(v2: Calibration) -> None:
    comp = v2.compensator()
    o = comp.step(0.0, math.nan, 0.0)
    assert math.isnan(o.bias_dps["x"]) and o.flags == EffectFlags.SKIPPED
    o = comp.step(1.0, 200.0, 0.0, t_on_s=-1.0)
    assert o.t_clamped and o.flags & EffectFlags.T_ON_CLAMPED
    with pytest.raises(CalibrationError, match=r"field 'axes'"):
        Compensator.load_state(v2, {"version": 1, "axes": {"x": {}}})
    with pytest.raises(CalibrationError, match=r"axes\.x.*missing field"):
        Compensator.load_state(v2, {"version": 1, "axes": {"x": {"version": 1}, "y": {}}})


_broken, _DELETE = broken, DELETE


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("effects.x.hysteresis.transition_c", 0.0,
         r"field 'effects.x.hysteresis.transition_c': must be > 0, got 0.0"),
        ("effects.x.hysteresis.transition_c", _DELETE,
         r"missing field 'effects.x.hysteresis.transition_c'"),
        ("effects.x.warmup.tau_s", "long", r"field 'effects.x.warmup.tau_s': expected a number"),
        ("effects.x.cubic.t_ref_c", 1e400,
         r"field 'effects.x.cubic.t_ref_c': the number 1e400 overflows a double"),
        ("effects.x.drift.colour", 1.0, r"field 'effects.x.drift.colour': unknown parameter"),
        ("effects.x.creep", {}, r"field 'effects.x.creep': unknown effect"),
        ("effects.x.warmup", [1.0, 2.0], r"field 'effects.x.warmup': expected an object"),
        ("effects.y", _DELETE, r"field 'effects': expected the axes of 'coefficients'"),
        ("effects", _DELETE, r"missing field 'effects'"),
        ("runtime_state.version", 2, r"field 'runtime_state': expected .*version 1"),
        ("runtime_state", _DELETE, r"missing field 'runtime_state'"),
        ("units.time", "ms", r"field 'units.time': expected 's', got 'ms'"),
        ("effectz", {}, r"unknown key\(s\) \['effectz'\] in the top level"),
        ("version", 1, r"unknown key\(s\) \['effects', 'runtime_state'\] in the top level"),
    ],
)
def test_bad_v2_files_name_file_and_field(
    v2: Calibration, tmp_path: Path, path: str, value: object, message: str
) -> None:
    p = tmp_path / "bad.json"
    text = json.dumps(_broken(v2.to_dict(), path, value)).replace("Infinity", "1e400")
    p.write_text(text)
    with pytest.raises(CalibrationError, match=message) as info:
        load_calibration(p)
    assert str(p) in str(info.value)


def test_drift_without_a_limit_and_effects_on_unknown_axes() -> None:
    cal = calibration_from_models(
        {"z": ExtendedModel(SCALING, {"drift": 0.0}, (*BASE_COLUMNS, "drift"),
                            (0.0, 0.0, 0.0, 0.0, 0.5), intercept_dps=0.0)},
        estimator=EstimatorConfig(), t_on_max_s=None,
        valid_range=ValidRange(-10.0, 10.0, -1.0, 1.0), provenance={})
    assert cal.to_dict()["effects"]["z"]["drift"] == {"slope_dps_per_h": 0.5, "t_on_max_s": None}
    back = Calibration.from_dict(json.loads(json.dumps(cal.to_dict())))
    assert back.compensator().step(7200.0, 0.0, 0.0).bias_dps["z"] == pytest.approx(
        1.0 + cal.base_bias("z", 0.0, 0.0), abs=1e-15)
    with pytest.raises(CalibrationError, match=r"effects: axes \['x'\] have no coefficients"):
        Calibration(cal.model, cal.scaling, cal.coefficients, cal.valid_range, cal.estimator,
                    effects={"x": Effects(warmup=Warmup(1.0, 2.0),
                                          hysteresis=Hysteresis(0.1, 0.5))})
