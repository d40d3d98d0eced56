"""The deployable nonparametric correction (compensation/_correction.py): its spline by
hand, its contract (refusals that name the field), the calibration file round trip, the
plausibility bound, and the online kernel adding it in the variable it names."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from gyrotherm import CalibrationError
from gyrotherm.compensation import Calibration, ValidRange, features, fit, parse_calibration
from gyrotherm.compensation._correction import MAX_KNOTS, Correction
from gyrotherm.compensation._effects import Effects, EffectsKernel
from gyrotherm.compensation._plausibility import check_plausible
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import chamber_runs

CORR = Correction("temperature_c", (0.0, 10.0, 20.0), (0.0, 1.0, -1.0), source="hand")


def test_value_is_the_linear_spline_and_constant_beyond_the_knots() -> None:
    # by hand: halfway up the first interval, a quarter into the second, the knots, outside
    assert CORR.value(5.0) == 0.5
    assert CORR.value(12.5) == pytest.approx(1.0 + 0.25 * (-2.0))
    assert [CORR.value(k) for k in (0.0, 10.0, 20.0)] == [0.0, 1.0, -1.0]
    assert CORR.value(-40.0) == 0.0 and CORR.value(85.0) == -1.0
    assert CORR.range == (0.0, 20.0) and CORR.max_abs_dps == 1.0


@pytest.mark.parametrize(("kwargs", "needle"), [
    ({"variable": "humidity"}, "Correction.variable: 'humidity'"),
    ({"knots": (0.0, 10.0, 10.0)}, "not strictly increasing at index 2"),
    ({"values_dps": (0.0, 1.0)}, "2 values for 3 knots"),
    ({"values_dps": (0.0, math.nan, 1.0)}, "values_dps[1]: expected a finite number"),
    ({"knots": (0.0, 1e400, 2.0)}, "knots[1]: expected a finite number"),
    ({"knots": (0.0,), "values_dps": (1.0,)}, "1 knots, expected 2"),
    ({"knots": tuple(range(MAX_KNOTS + 1)), "values_dps": (0.0,) * (MAX_KNOTS + 1)},
     f"{MAX_KNOTS + 1} knots"),
    ({"knots": "0,1,2"}, "expected a list of numbers"),
])
def test_contract_refusals_name_the_field(kwargs: dict[str, object], needle: str) -> None:
    args = {"variable": "temperature_c", "knots": (0.0, 10.0, 20.0),
            "values_dps": (0.0, 1.0, -1.0), **kwargs}
    with pytest.raises(CalibrationError, match=None) as exc:
        Correction(**args)  # type: ignore[arg-type]
    assert needle in str(exc.value)


@pytest.fixture(scope="module")
def paper() -> Calibration:
    est = EstimatorConfig(tau_s=120.0)
    runs = chamber_runs([10, 40], seed=3, rate_hz=1.0, hold_s=600.0)
    return fit([features(r, est) for r in runs], "paper", estimator=est)


def _with(cal: Calibration, corr: Correction, axis: str = "x") -> Calibration:
    return replace(cal, effects={axis: Effects(correction=corr)})


def test_file_round_trip_and_version(paper: Calibration, tmp_path) -> None:
    cal = _with(paper, CORR)
    assert cal.version == 2 and cal.effect_names("x") == ("correction",)
    doc = json.loads(cal.save(tmp_path / "c.json").read_text())
    assert doc["effects"]["x"]["correction"] == {
        "variable": "temperature_c", "knots": [0.0, 10.0, 20.0],
        "values_dps": [0.0, 1.0, -1.0], "source": "hand"}
    back = parse_calibration(json.dumps(doc))
    assert back.effects_of("x").correction == CORR
    assert back.effect_names("y") == ()


@pytest.mark.parametrize(("edit", "needle"), [
    (lambda c: c.update(knots=[0.0, 5.0]), "field 'effects.x.correction': Correction."
                                           "values_dps: 3 values for 2 knots"),
    (lambda c: c.pop("values_dps"), "missing field 'effects.x.correction.values_dps'"),
    (lambda c: c.update(order=3), "field 'effects.x.correction.order': unknown parameter"),
    (lambda c: c.update(variable=7), "field 'effects.x.correction'"),
])
def test_bad_correction_in_a_file_names_the_field(paper: Calibration, edit, needle: str) -> None:
    doc = json.loads(json.dumps(_with(paper, CORR).to_dict()))
    edit(doc["effects"]["x"]["correction"])
    with pytest.raises(CalibrationError) as exc:
        parse_calibration(json.dumps(doc), source="cal.json")
    assert "cal.json" in str(exc.value) and needle in str(exc.value)


def test_plausibility_bounds_the_correction(paper: Calibration) -> None:
    check_plausible(_with(paper, CORR))
    huge = Correction("delta_t_c", (-1.0, 1.0), (0.0, 45.0))
    with pytest.raises(CalibrationError, match=r"axis 'x', effect 'correction': parameter "
                       r"'values_dps' gives \|bias\| up to 45"):
        check_plausible(_with(paper, huge))


@pytest.mark.parametrize("variable", ["temperature_c", "delta_t_c", "time_since_power_on_s"])
def test_kernel_adds_the_correction_in_its_variable(variable: str) -> None:
    corr = Correction(variable, (-5.0, 0.0, 30.0, 600.0), (0.3, -0.1, 0.2, 0.05))
    limits = ValidRange(20.0, 25.0, -0.5, 0.5)  # the base's clamp does not touch it
    kernel = EffectsKernel(Effects(correction=corr), limits)
    rows = [(0.0, 18.0, -2.0, 0.0), (10.0, 27.0, 0.7, 10.0), (700.0, 40.0, 3.0, 700.0)]
    for t, temp, dt, t_on in rows:
        out = kernel.step(t, temp, dt, t_on)
        v = {"temperature_c": temp, "delta_t_c": dt, "time_since_power_on_s": t_on}[variable]
        assert out.bias_dps == corr.value(v)  # T and ΔT unclamped, as the diagnosis fits
    series = EffectsKernel(Effects(correction=corr), limits).series(
        *(np.array(c) for c in zip(*rows, strict=True)))
    assert series.bias_dps.tolist() == [corr.value({"temperature_c": r[1], "delta_t_c": r[2],
                                         "time_since_power_on_s": r[3]}[variable])
                                         for r in rows]


def test_autopilot_steady_state_includes_a_correction_in_temperature(paper: Calibration) -> None:
    from gyrotherm.cli._export import steady_state_bias

    temps = np.array([-50.0, 5.0, 15.0, 25.0, 90.0])  # below, inside, above the knots
    plain = steady_state_bias(paper, "x", temps)
    with_t = steady_state_bias(_with(paper, CORR), "x", temps)
    assert with_t - plain == pytest.approx([CORR.value(t) for t in temps.tolist()])
    in_dt = Correction("delta_t_c", (-1.0, 1.0), (0.2, 0.4))
    assert steady_state_bias(_with(paper, in_dt), "x", temps) - plain == pytest.approx(0.3)
    in_time = Correction("time_since_power_on_s", (0.0, 600.0), (0.2, 0.0))
    assert steady_state_bias(_with(paper, in_time), "x", temps) == pytest.approx(plain)
