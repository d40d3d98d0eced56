"""Calibrations that cannot hurt: absurd v1/v2 files are refused naming the axis, the
effect, the parameter and the bound; the bound is what the module docstring says
(hand-computed cases); and, fuzzed, every calibration file that loads can never make
the compensator predict more than the bound, whatever the runtime state."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gyrotherm import CalibrationError
from gyrotherm.codecs import Run
from gyrotherm.compensation import Calibration, features, fit, parse_calibration
from gyrotherm.compensation._plausibility import MAX_BIAS_DPS, check_plausible
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs


@pytest.fixture(scope="module")
def v1() -> Calibration:
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    runs: list[Run] = chamber_runs([5, 20], seed=3, rate_hz=1.0, hold_s=600)
    return fit([features(r, est) for r in runs], "paper", estimator=est)


@pytest.fixture(scope="module")
def v2_doc(v1: Calibration) -> dict[str, Any]:
    doc = v1.to_dict()
    doc["version"] = 2
    doc["units"]["time"] = "s"
    doc["runtime_state"] = {"version": 1, "per": "axis", "fields": [
        "samples", "time_s", "power_on_s", "structure_temperature_c", "hysteresis_direction",
        "hysteresis_high_c", "hysteresis_low_c", "hysteresis_travel_c", "hysteresis_h_start",
        "hysteresis_h"]}
    doc.pop("coefficients_physical", None)
    doc["effects"] = {a: {} for a in v1.axes}
    doc["effects"]["x"] = {
        "thermal_lag": {"tau_s": 90.0},
        "hysteresis": {"amplitude_dps": 0.05, "transition_c": 0.4},
        "warmup": {"amplitude_dps": 0.2, "tau_s": 300.0},
        "cubic": {"coefficient_dps_per_c3": 1e-6, "t_ref_c": 15.0},
        "gradient_quadratic": {"coefficient_dps_per_c2": 0.001},
        "drift": {"slope_dps_per_h": 0.01, "t_on_max_s": 7200.0},
    }
    return doc


def _with(doc: dict[str, Any], path: str, value: Any) -> str:
    out = copy.deepcopy(doc)
    node = out
    keys = path.split(".")
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return json.dumps(out)


def test_sane_v1_and_v2_load(v1: Calibration, v2_doc: dict[str, Any]) -> None:
    check_plausible(v1)
    cal = parse_calibration(json.dumps(v2_doc), source="v2.json")
    assert cal.effect_names("x") == ("thermal_lag", "hysteresis", "warmup", "cubic",
                                     "gradient_quadratic", "drift")


@pytest.mark.parametrize(("path", "value", "message"), [
    ("effects.x.hysteresis.amplitude_dps", 1e6,
     r"axis 'x', effect 'hysteresis': parameter 'amplitude_dps' gives \|bias\| up to 1e\+06 "
     r"°/s \(\|A\|\), more than the 30 °/s bound"),
    ("effects.x.hysteresis.amplitude_dps", 1e308, r"axis 'x', effect 'hysteresis'"),
    ("effects.x.warmup.amplitude_dps", -1e6, r"effect 'warmup': parameter 'amplitude_dps'"),
    ("effects.x.drift.slope_dps_per_h", 1e6,
     r"effect 'drift': parameter 'slope_dps_per_h' gives \|bias\| up to 2e\+06 °/s "
     r"\(\|s\|·7200 s/3600\)"),
    ("effects.x.thermal_lag.tau_s", 1e300,
     r"effect 'thermal_lag': parameter 'tau_s' = 1e\+300 s is outside the physical range "
     r"\[0.001, 86400\] s"),
    ("effects.x.warmup.tau_s", 1e-9, r"effect 'warmup': parameter 'tau_s' = 1e-09 s"),
    ("effects.x.hysteresis.transition_c", 1e6,
     r"effect 'hysteresis': parameter 'transition_c' = 1000000.0 °C is wider"),
    ("effects.x.drift.t_on_max_s", 1e12,
     r"effect 'drift': parameter 't_on_max_s' = 1000000000000.0 s is more than"),
    ("effects.x.warmup.amplitude_dps", 29.99, r"axis 'x', whole model: \|bias\| can reach"),
    ("range.t_max_c", 1000.0, r"range: temperature \[.*, 1000\] °C is outside \[-100, 200\]"),
])
def test_absurd_v2_files_are_refused_naming_effect_parameter_and_bound(
        v2_doc: dict[str, Any], path: str, value: float, message: str) -> None:
    with pytest.raises(CalibrationError, match=rf"^v2.json: (axis 'x', )?{message}"):
        parse_calibration(_with(v2_doc, path, value), source="v2.json")


def test_absurd_v1_coefficients_are_refused(v1: Calibration) -> None:
    doc = v1.to_dict()
    doc.pop("coefficients_physical", None)
    doc["coefficients"]["y"] = [1e6] * len(doc["coefficients"]["y"])
    with pytest.raises(CalibrationError, match=r"^v1.json: axis 'y', base polynomial: "
                       r"\|bias\| reaches .* °/s over the valid range, more than the 30"):
        parse_calibration(json.dumps(doc), source="v1.json")


def test_the_bound_is_the_hand_computed_one(v2_doc: dict[str, Any]) -> None:
    """cubic c = 2e-4 with T_ref 15 °C over the range: |c|·max(|t_min − 15|, |t_max − 15|)³;
    a value just above 30 °/s is refused, just below accepted."""
    r = v2_doc["range"]
    reach = max(abs(r["t_min_c"] - 15.0), abs(r["t_max_c"] - 15.0))
    c_limit = MAX_BIAS_DPS / reach**3
    with pytest.raises(CalibrationError, match=r"effect 'cubic'"):
        parse_calibration(_with(v2_doc, "effects.x.cubic.coefficient_dps_per_c3",
                                c_limit * 1.01), source="v2.json")
    # just below the bound alone: then the whole model (base + the others) is over it
    with pytest.raises(CalibrationError, match=r"whole model"):
        parse_calibration(_with(v2_doc, "effects.x.cubic.coefficient_dps_per_c3",
                                c_limit * 0.99), source="v2.json")
    # a tenth of it is fine
    parse_calibration(_with(v2_doc, "effects.x.cubic.coefficient_dps_per_c3", c_limit * 0.1),
                      source="v2.json")


def test_a_file_on_disk_is_refused_the_same(tmp_path: Path, v2_doc: dict[str, Any]) -> None:
    from gyrotherm.compensation import read_calibration

    p = tmp_path / "cal.json"
    p.write_text(_with(v2_doc, "effects.x.hysteresis.amplitude_dps", 1e6))
    with pytest.raises(CalibrationError, match=rf"^{p}: axis 'x', effect 'hysteresis'"):
        read_calibration(p)


_LEAVES = [
    "effects.x.thermal_lag.tau_s", "effects.x.hysteresis.amplitude_dps",
    "effects.x.hysteresis.transition_c", "effects.x.warmup.amplitude_dps",
    "effects.x.warmup.tau_s", "effects.x.cubic.coefficient_dps_per_c3",
    "effects.x.cubic.t_ref_c", "effects.x.gradient_quadratic.coefficient_dps_per_c2",
    "effects.x.drift.slope_dps_per_h", "effects.x.drift.t_on_max_s",
    "range.t_min_c", "range.t_max_c", "range.dt_min_c", "range.dt_max_c",
    "scaling.t_ref_c", "scaling.t_scale_c", "scaling.dt_scale_c",
]
_NUMBERS = st.one_of(st.floats(allow_nan=False, allow_infinity=False),
                     st.sampled_from([1e308, -1e308, 1e6, -1e6, 1e-300, 0.0, 30.0, 1e300]))


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(st.tuples(st.sampled_from(_LEAVES), _NUMBERS), min_size=1, max_size=3),
       coefficient=st.tuples(st.integers(0, 2), st.integers(0, 4), _NUMBERS))
def test_fuzz_every_loadable_calibration_stays_within_the_bound(
        v2_doc: dict[str, Any], edits: list[tuple[str, float]],
        coefficient: tuple[int, int, float]) -> None:
    """Random leaves replaced (and one coefficient): either refused with a
    CalibrationError, or every bias the compensator gives, from power-on through
    heating, cooling, T and ΔT far outside the range and t_on up to 10 days, is finite
    and within MAX_BIAS_DPS."""
    doc = copy.deepcopy(v2_doc)
    for path, value in edits:
        doc = json.loads(_with(doc, path, value))
    axis, k, value = coefficient
    doc["coefficients"]["xyz"[axis]][k] = value
    try:
        cal = parse_calibration(json.dumps(doc), source="fuzz.json")
    except CalibrationError:
        return
    comp = cal.compensator()
    t = np.concatenate([np.linspace(0, 3600, 60), np.linspace(3600, 864000, 20)])
    temp = np.concatenate([np.linspace(-150, 250, 40), np.linspace(250, -150, 40)])
    dt = np.concatenate([np.linspace(-2000, 2000, 40), np.linspace(2000, -2000, 40)])
    for ti, ci, di in zip(t.tolist(), temp.tolist(), dt.tolist(), strict=True):
        b = comp.step(ti, ci, di, ti)
        for v in b.bias_dps.values():
            assert math.isfinite(v) and abs(v) <= MAX_BIAS_DPS * (1 + 1e-9), (ti, ci, di, v)


@pytest.mark.parametrize("model", ["paper", "t2", "t3"])
@pytest.mark.parametrize("seed", range(8))
def test_the_base_polynomials_maximum_is_exact(v1: Calibration, model: str, seed: int) -> None:
    """The plain-float maximum of |base polynomial| over the valid box against a dense
    numpy grid (401 T × 41 ΔT, the box's corners and edges on it): never below it, and
    above it by no more than the grid can miss between its points (a vertex of a
    curvature this large moves |bias| by ≈ curvature·(step/2)²)."""
    from dataclasses import replace

    from gyrotherm.compensation import ValidRange, get_model
    from gyrotherm.compensation._plausibility import _base_max, _base_max_grid

    rng = np.random.default_rng(seed)
    spec = get_model(model)
    lo = float(rng.uniform(-40, 20))
    box = ValidRange(lo, lo + float(rng.uniform(5, 80)), -float(rng.uniform(0.5, 8)),
                     float(rng.uniform(0.5, 8)))
    coefficients = {a: tuple(float(c) for c in rng.normal(0.0, 0.5, len(spec.terms)))
                    for a in v1.axes}
    cal = replace(v1, model=spec, coefficients=coefficients, valid_range=box)
    t = np.linspace(box.t_min_c, box.t_max_c, 401)
    d = np.linspace(box.dt_min_c, box.dt_max_c, 41)
    tt, dd = np.meshgrid(t, d)
    for a in cal.axes:
        dense = float(np.max(np.abs(cal.base_series(a, tt.ravel(), dd.ravel()))))
        exact = _base_max(cal, a)
        assert dense <= exact * (1 + 1e-12) + 1e-12
        assert exact <= dense * (1 + 1e-3) + 1e-9
        assert exact >= _base_max_grid(cal, a) * (1 - 1e-12) - 1e-12
