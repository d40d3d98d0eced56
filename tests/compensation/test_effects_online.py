"""The online effects kernel against independent truth: the diagnosis' vectorised
columns (``gyrotherm.analysis``), hand-computed cases, a fine-grid reference for
irregular steps, and state round trips."""

from __future__ import annotations

import json
import math

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm import CalibrationError
from gyrotherm.analysis import direction_state, lowpass
from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel, design, hysteresis_state
from gyrotherm.compensation import Scaling, ValidRange, get_model
from gyrotherm.compensation._effects import (
    Cubic,
    Drift,
    EffectFlags,
    Effects,
    EffectsKernel,
    EffectsState,
    GradientQuadratic,
    Hysteresis,
    ThermalLag,
    Warmup,
)


def chamber_like(n: int, seed: int, *, step_s: float = 1.0) -> tuple[np.ndarray, ...]:
    """Time, T and ΔT of hold → ramp up → hold → ramp down with noise (seeded)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * step_s
    knots = np.array([0.0, 0.15, 0.45, 0.6, 0.9, 1.0]) * t[-1]
    temp = np.interp(t, knots, [-20.0, -20.0, 50.0, 50.0, 10.0, 10.0])
    temp = temp + np.cumsum(rng.normal(0.0, 0.02, n)) + rng.normal(0.0, 0.01, n)
    return t, temp, 120.0 * np.gradient(temp, t)


# --- equal to the diagnosis' columns on uniform grids ---------------------------------


@pytest.mark.parametrize(("tau_s", "step_s"), [(37.5, 1.0), (600.0, 1.0), (12.0, 0.1)])
def test_lag_on_a_uniform_grid_equals_lowpass(tau_s: float, step_s: float) -> None:
    t, temp, dtemp = chamber_like(3000, 1, step_s=step_s)
    k = EffectsKernel(Effects(thermal_lag=ThermalLag(tau_s)))
    got = k.series(t, temp, dtemp).structure_temperature_c
    assert np.max(np.abs(got - lowpass(temp, tau_s, step_s=step_s))) < 1e-12


@pytest.mark.parametrize("seed", [2, 3])
def test_hysteresis_equals_the_play_operator_and_saturation(seed: int) -> None:
    # quantised readings (0.125 °C, binary-exact) and w = 0.25 °C: many moves of
    # exactly w, which must not flip (strict >), alongside real flips
    t, temp, dtemp = chamber_like(4000, seed)
    temp = np.round(temp * 8.0) / 8.0
    k = EffectsKernel(Effects(hysteresis=Hysteresis(amplitude_dps=1.0, transition_c=0.25)))
    rows, at_w = [], 0
    for row in zip(t.tolist(), temp.tolist(), dtemp.tolist(), t.tolist(), strict=True):
        s = k.state
        v, d = row[1], s.hysteresis_direction
        at_w += s.samples > 0 and ((d >= 0 and max(s.hysteresis_high_c, v) - v == 0.25)
                                   or (d <= 0 and v - min(s.hysteresis_low_c, v) == 0.25))
        o = k.step(*row)
        rows.append((o.bias_dps, k.state.hysteresis_direction, k.state.hysteresis_h))
    direction = direction_state(temp, 0.25)
    assert [r[1] for r in rows] == direction.tolist()  # bit-exact
    h = hysteresis_state(temp, direction, 0.25)
    assert np.max(np.abs(np.array([r[0] for r in rows]) - h)) < 1e-12
    assert np.array_equal([r[2] for r in rows], [r[0] for r in rows])
    assert np.count_nonzero(np.diff(direction)) >= 4 and at_w >= 10


def test_hysteresis_follows_the_lagged_temperature() -> None:
    t, temp, dtemp = chamber_like(4000, 4)
    k = EffectsKernel(Effects(thermal_lag=ThermalLag(90.0),
                              hysteresis=Hysteresis(amplitude_dps=0.5, transition_c=0.3)))
    out = k.series(t, temp, dtemp)
    ts = lowpass(temp, 90.0)
    want = 0.5 * hysteresis_state(ts, direction_state(ts, 0.3), 0.3)
    assert np.max(np.abs(out.bias_dps - want)) < 1e-12
    assert np.count_nonzero(np.diff(direction_state(ts, 0.3))) >= 2


def test_full_model_equals_extended_model_bias() -> None:
    """Base polynomial at the kernel's T̂_s and ΔT̂ plus the kernel's bias is the fitted
    model's bias from the diagnosis' vectorised columns (``design``), every effect at
    once (coefficients chosen by hand); ``ExtendedModel.bias`` (on the kernel) too."""
    t, temp, dtemp = chamber_like(5000, 5)
    scaling = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=8.0)
    effects = {"thermal_lag": 75.0, "hysteresis": 0.35, "warmup": 400.0, "cubic": 0.0,
               "gradient_quadratic": 0.0, "drift": 0.0}
    columns = (*BASE_COLUMNS, "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift")
    coefficients = (0.02, -0.05, 0.03, 0.004, 0.012, -0.08, 0.006, -0.002, 0.003)
    model = ExtendedModel(scaling, effects, columns, coefficients, intercept_dps=0.7)
    kernel = EffectsKernel(Effects.from_params(model.params(), t_ref_c=scaling.t_ref_c))
    out = kernel.series(t, temp, dtemp)
    x, g = scaling.centre(out.structure_temperature_c, out.delta_t_c)
    base = get_model("paper").design(x, g) @ np.array([*coefficients[:4], 0.7])
    names, columns_matrix = design(t, temp, dtemp, scaling, effects, step_s=1.0)
    assert names == columns
    want = columns_matrix @ np.array(coefficients) + 0.7
    assert np.max(np.abs(base + out.bias_dps - want)) < 1e-12
    assert np.max(np.abs(model.bias(t, temp, dtemp) - want)) < 1e-12
    assert np.ptp(want) > 0.1  # the effects are not negligible on this run
    assert not out.flags.any()


# --- hand-computed cases --------------------------------------------------------------


def test_three_sample_lag_by_hand() -> None:
    k = EffectsKernel(Effects(thermal_lag=ThermalLag(10.0)))
    assert k.step(0.0, 20.0, 0.0, 0.0).structure_temperature_c == 20.0
    y1 = 20.0 + (1.0 - math.exp(-1.0)) * 10.0  # dt = 10 s, input stepped to 30 °C
    assert k.step(10.0, 30.0, 0.0, 10.0).structure_temperature_c == pytest.approx(y1, abs=1e-14)
    y2 = y1 + (1.0 - math.exp(-1.5)) * (30.0 - y1)  # dt = 15 s
    assert k.step(25.0, 30.0, 0.0, 25.0).structure_temperature_c == pytest.approx(y2, abs=1e-14)


def test_hysteresis_flip_exactly_at_w_and_beyond_by_hand() -> None:
    w = 0.5
    k = EffectsKernel(Effects(hysteresis=Hysteresis(amplitude_dps=2.0, transition_c=w)))
    seq = [20.0, 20.5, 20.75, 21.0, 20.5, 20.25]
    got = [(k.step(float(i), v, 0.0, float(i)).bias_dps, k.state.hysteresis_direction)
           for i, v in enumerate(seq)]
    # 20.5: risen exactly w — no flip; 20.75: 0.75 > w — flip to +1, D = this step 0.25
    assert got[0] == (0.0, 0) and got[1] == (0.0, 0)
    h2 = 1.0 - math.exp(-0.25 / w)
    h3 = 1.0 - math.exp(-0.5 / w)  # D = 0.25 + 0.25
    assert got[2][1] == 1 and got[2][0] == pytest.approx(2.0 * h2, abs=1e-15)
    assert got[3][1] == 1 and got[3][0] == pytest.approx(2.0 * h3, abs=1e-15)
    # 20.5: fallen exactly w below the high 21.0 — still +1, travel pushes h on
    h4 = 1.0 - math.exp(-1.0 / w)
    assert got[4][1] == 1 and got[4][0] == pytest.approx(2.0 * h4, abs=1e-15)
    # 20.25: 0.75 below the high — flip to −1 from h₀ = h4, D = 0.25
    h5 = -1.0 + (h4 + 1.0) * math.exp(-0.25 / w)
    assert got[5][1] == -1 and got[5][0] == pytest.approx(2.0 * h5, abs=1e-15)


def test_falling_wins_a_tie() -> None:
    # the tie needs hi − lo > 2w while d = 0, which no sample path reaches from a
    # start (the spread flips the state first): set it through a restored state
    state = EffectsState(samples=5, time_s=4.0, structure_temperature_c=21.0,
                         hysteresis_high_c=22.0, hysteresis_low_c=20.0)
    k = EffectsKernel(Effects(hysteresis=Hysteresis(1.0, 0.5)), state=state)
    k.step(5.0, 21.0, 0.0, 5.0)
    assert k.state.hysteresis_direction == -1 and k.state.hysteresis_low_c == 21.0


def test_stateless_terms_clamping_and_power_on_time_by_hand() -> None:
    effects = Effects(warmup=Warmup(0.2, 100.0), cubic=Cubic(1e-4, 20.0),
                      gradient_quadratic=GradientQuadratic(0.01),
                      drift=Drift(0.036, t_on_max_s=7200.0))
    limits = ValidRange(t_min_c=-10.0, t_max_c=40.0, dt_min_c=-3.0, dt_max_c=4.0)
    k = EffectsKernel(effects, limits)
    o = k.step(1000.0, 30.0, 2.0, 50.0)
    want = 0.2 * math.exp(-0.5) + 1e-4 * 1000.0 + 0.01 * 4.0 + 0.036 * 50.0 / 3600.0
    assert o.bias_dps == pytest.approx(want, abs=1e-15) and o.flags == 0
    assert k.state.power_on_s == 950.0 and k.state.time_on_s(1010.0) == 60.0
    o = k.step(10000.0, 55.0, -5.0, 9050.0)  # T, ΔT beyond the range; t_on > t_on_max
    assert (o.structure_temperature_c, o.delta_t_c) == (40.0, -3.0)
    want = 0.2 * math.exp(-90.5) + 1e-4 * 8000.0 + 0.01 * 9.0 + 0.036 * 2.0
    assert o.bias_dps == pytest.approx(want, abs=1e-15)
    assert o.flags == EffectFlags.T_CLAMPED | EffectFlags.DT_CLAMPED | EffectFlags.T_ON_CLAMPED
    assert k.state.structure_temperature_c == 55.0  # the state is not clamped
    o = k.step(10001.0, 30.0, 0.0, -5.0)  # before power-on: counted as t_on = 0
    assert o.flags == EffectFlags.T_ON_CLAMPED
    assert o.bias_dps == pytest.approx(0.2 + 1e-4 * 1000.0, abs=1e-15)


def test_skipped_and_reversed_samples() -> None:
    k = EffectsKernel(Effects(thermal_lag=ThermalLag(10.0), hysteresis=Hysteresis(1.0, 0.5)))
    o = k.step(0.0, math.nan, 0.0, 0.0)
    assert math.isnan(o.structure_temperature_c) and o.bias_dps == 0.0
    assert o.flags == EffectFlags.SKIPPED and k.state.samples == 0
    first = k.step(1.0, 20.0, 0.0, 1.0)
    before = k.state.to_dict()
    for bad in ((2.0, math.inf, 0.0, 2.0), (2.0, 20.0, math.nan, 2.0),
                (math.nan, 20.0, 0.0, 2.0), (2.0, 20.0, 0.0, -math.inf), (2.0, 2e4, 0.0, 2.0)):
        o = k.step(*bad)
        assert o == first._replace(flags=EffectFlags.SKIPPED) and k.state.to_dict() == before
    o = k.step(0.5, 30.0, 0.0, 0.5)  # time ran backwards: dt = 0, the clock re-bases
    assert o.flags == EffectFlags.TIME_REVERSED and o.structure_temperature_c == 20.0
    assert k.state.time_s == 0.5
    k.reset()
    assert k.state == EffectsState() and k.step(0.0, 25.0, 0.0, 0.0)[0] == 25.0


# --- irregular time steps ---------------------------------------------------------------


def test_irregular_steps_match_a_fine_grid_reference() -> None:
    """Temperature frames at 10–100 Hz with jitter, against the lag of the continuous
    signal on a 1-ms grid. The zero-order hold takes each frame's T over the interval
    before it: on a ramp of rate r the lag runs ahead by r·dt/2 at most, so the
    tolerance is max|Ṫ|·max(dt)/2 + the grid's own r·1 ms/2."""
    rng = np.random.default_rng(6)
    tau, h = 40.0, 1e-3
    fine = np.arange(0.0, 600.0 + h / 2, h)
    signal = 20.0 + 10.0 * np.sin(2 * np.pi * fine / 200.0) + 0.05 * fine  # |Ṫ| ≤ 0.37 °C/s
    times = np.cumsum(rng.uniform(0.01, 0.1, 12000))
    times = np.round(times[times < 600.0] / h) * h  # frames on the fine grid
    idx = np.round(times / h).astype(int)
    k = EffectsKernel(Effects(thermal_lag=ThermalLag(tau)))
    got = k.series(times, signal[idx], np.zeros(len(idx))).structure_temperature_c
    ref = lowpass(signal[idx[0]:], tau, step_s=h)[idx - idx[0]]
    rate = float(np.max(np.abs(np.gradient(signal, h))))
    tol = rate * float(np.max(np.diff(times))) / 2 + rate * h / 2
    err = float(np.max(np.abs(got - ref)))
    assert err < tol and tol < 0.02
    # and the step response of a held input is exact, whatever the spacing
    held = signal[idx]
    fine_held = np.repeat(held[1:], np.diff(idx))
    exact = lowpass(np.r_[held[0], fine_held], tau, step_s=h)[idx - idx[0]]
    assert np.max(np.abs(got - exact)) < 1e-9


# --- state: round trips, validation, robustness ---------------------------------------

ALL = Effects(thermal_lag=ThermalLag(50.0), hysteresis=Hysteresis(0.3, 0.2),
              warmup=Warmup(-0.1, 300.0), cubic=Cubic(2e-5, 15.0),
              gradient_quadratic=GradientQuadratic(0.002), drift=Drift(0.01))


@pytest.mark.parametrize("codec", ["json", "msgpack"])
def test_state_round_trip_continues_bit_exact(codec: str) -> None:
    rng = np.random.default_rng(7)
    t, temp, dtemp = chamber_like(2000, 7)
    t = t + rng.uniform(-0.2, 0.2, len(t))  # irregular
    whole = EffectsKernel(ALL).series(t, temp, dtemp, t + 30.0)
    first = EffectsKernel(ALL)
    first.series(t[:777], temp[:777], dtemp[:777], t[:777] + 30.0)
    d = first.state.to_dict()
    raw = json.loads(json.dumps(d)) if codec == "json" else msgpack.unpackb(msgpack.packb(d))
    second = EffectsKernel(ALL, state=EffectsState.from_dict(raw))
    assert second.state == first.state
    rest = second.series(t[777:], temp[777:], dtemp[777:], t[777:] + 30.0)
    for name in ("structure_temperature_c", "delta_t_c", "bias_dps", "flags"):
        assert np.array_equal(getattr(rest, name), getattr(whole, name)[777:])


def test_state_from_dict_names_the_bad_field() -> None:
    good = EffectsState(samples=3, hysteresis_direction=1).to_dict()
    cases = [({**good, "hysteresis_direction": 2}, "hysteresis_direction"),
             ({**good, "samples": 1.5}, "'samples'"), ({**good, "time_s": True}, "'time_s'"),
             ({**good, "time_s": math.nan}, "not finite"), ({**good, "version": 2}, "version"),
             ({k: v for k, v in good.items() if k != "hysteresis_h"}, "missing"),
             ({**good, "extra": 1.0}, "unknown"), ({**good, "hysteresis_h": 1.5}, "> 1")]
    for data, match in cases:
        with pytest.raises(CalibrationError, match=match):
            EffectsState.from_dict(data)


def test_parameters_round_trip_and_are_validated() -> None:
    assert Effects.from_params(ALL.to_params()) == ALL
    assert ALL.names == ("thermal_lag", "hysteresis", "warmup", "cubic",
                         "gradient_quadratic", "drift")
    with pytest.raises(CalibrationError, match="unknown effect 'creep'"):
        Effects.from_params({"creep": {}})
    with pytest.raises(CalibrationError, match="expected"):
        Effects.from_params({"warmup": {"amplitude_dps": 1.0}})
    with pytest.raises(CalibrationError, match="tau_s: must be > 0"):
        ThermalLag(0.0)
    with pytest.raises(CalibrationError, match="finite"):
        Cubic(math.inf, 20.0)


values = (st.floats(allow_nan=True, allow_infinity=True)
          | st.floats(-200.0, 200.0) | st.sampled_from([0.0, 1e4, -1e4, 1e12, 1e308]))


@settings(derandomize=True, max_examples=200, deadline=None, database=None)
@given(st.lists(st.tuples(values, values, values, values), min_size=1, max_size=40))
def test_state_stays_finite_on_any_input(rows: list[tuple[float, ...]]) -> None:
    k = EffectsKernel(ALL, ValidRange(-40.0, 85.0, -20.0, 20.0))
    for row in rows:
        before = k.state.to_dict()
        o = k.step(*row)
        d = k.state.to_dict()
        assert all(math.isfinite(v) for v in d.values())
        assert abs(d["hysteresis_h"]) <= 1.0 and d["hysteresis_direction"] in (-1, 0, 1)
        if o.flags & EffectFlags.SKIPPED:
            assert d == before
        else:
            assert math.isfinite(o.bias_dps) and -40.0 <= o.structure_temperature_c <= 85.0
        assert EffectsState.from_dict(json.loads(json.dumps(d))) == k.state
