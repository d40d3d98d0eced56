"""Off-catalogue shapes of issue 19, must-show item 2: a periodic bias in T, a
saturating and a |ΔT| response to the gradient, a hysteresis whose width grows with
|dT/dt|. Their formulas against hand-computed values, the ``where`` span against the
generator's truth, and the diagnosis of one shape per variable on development seeds.

SHAPE_EVAL_SEEDS are fixed here and in scripts/generalisation_sweep.py before the
shapes existed and before any result on them was seen; they are never used while
developing (tests use SHAPE_DEV_SEEDS only)."""

from __future__ import annotations

import math
from dataclasses import replace
from types import ModuleType

import numpy as np
import pytest

from gyrotherm._errors import ConfigError
from gyrotherm.analysis import Diagnosis, SynthConfig, diagnose
from gyrotherm.analysis._where import segments, significant_runs, support_span
from gyrotherm.analysis.synth._variants import (
    VariantTruth,
    shape_bias,
    stop_operator,
    variant_runs,
)

from .conftest import CORNER_CFG

SHAPE_DEV_SEEDS = (31, 32, 33, 34, 35, 36)
SHAPE_EVAL_SEEDS = (301, 302, 303, 304, 305)
"""Fixed (the commit adding this line) before any result on them was seen."""
SHAPE_EVAL2_SEEDS = (321, 322, 323, 324, 325)
"""The second set, fixed (the commit adding this line) before the changes it scores."""
SHAPE_EVAL3_SEEDS = (341, 342, 343, 344, 345)
"""The third set, fixed (the commit adding this line) before the change it scores."""
SHAPE_EVAL4_SEEDS = (361, 362, 363, 364, 365)
"""The fourth set, fixed (the commit adding this line) before the change it scores."""
SHAPE_DEV2_SEEDS = (41, 42, 43, 44, 45, 46, 47, 48, 49, 50)
"""Round 5's development seeds."""
SHAPE_EVAL5_SEEDS = (381, 382, 383, 384, 385)
"""The fifth set, fixed (the commit adding this line) before round 5's changes."""


def test_shape_eval_seeds_are_fixed_and_disjoint(sweep: ModuleType) -> None:
    assert sweep.SHAPE_DEV_SEEDS == SHAPE_DEV_SEEDS
    assert sweep.SHAPE_EVAL_SEEDS == SHAPE_EVAL_SEEDS
    used = {*sweep.DEV_SEEDS, *sweep.EVAL_SEEDS, *SHAPE_DEV_SEEDS}
    assert not set(SHAPE_EVAL_SEEDS) & used
    assert sweep.SHAPE_EVAL2_SEEDS == SHAPE_EVAL2_SEEDS
    assert not set(SHAPE_EVAL2_SEEDS) & {*used, *SHAPE_EVAL_SEEDS, *sweep.NULL_EVAL_SEEDS,
                                          *sweep.NULL_DEV_SEEDS, *sweep.NULL_CONFIRM_SEEDS}
    assert sweep.SHAPE_EVAL3_SEEDS == SHAPE_EVAL3_SEEDS
    assert not set(SHAPE_EVAL3_SEEDS) & {*used, *SHAPE_EVAL_SEEDS, *SHAPE_EVAL2_SEEDS,
                                          *sweep.NULL_EVAL_SEEDS, *sweep.NULL_DEV_SEEDS,
                                          *sweep.NULL_CONFIRM_SEEDS}
    assert sweep.SHAPE_EVAL4_SEEDS == SHAPE_EVAL4_SEEDS
    assert not set(SHAPE_EVAL4_SEEDS) & {*used, *SHAPE_EVAL_SEEDS, *SHAPE_EVAL2_SEEDS,
                                          *SHAPE_EVAL3_SEEDS, *sweep.NULL_EVAL_SEEDS,
                                          *sweep.NULL_DEV_SEEDS, *sweep.NULL_CONFIRM_SEEDS,
                                          *sweep.NULL_CONFIRM2_SEEDS}
    assert sweep.SHAPE_DEV2_SEEDS == SHAPE_DEV2_SEEDS
    assert sweep.SHAPE_EVAL5_SEEDS == SHAPE_EVAL5_SEEDS
    assert not set(SHAPE_DEV2_SEEDS) & {*used, *SHAPE_EVAL_SEEDS, *SHAPE_EVAL2_SEEDS,
                                         *SHAPE_EVAL3_SEEDS, *SHAPE_EVAL4_SEEDS}
    assert not set(SHAPE_EVAL5_SEEDS) & {*used, *SHAPE_DEV2_SEEDS, *SHAPE_EVAL_SEEDS,
                                          *SHAPE_EVAL2_SEEDS, *SHAPE_EVAL3_SEEDS,
                                          *SHAPE_EVAL4_SEEDS, *sweep.NULL_EVAL_SEEDS,
                                          *sweep.NULL_DEV_SEEDS, *sweep.NULL_CONFIRM_SEEDS,
                                          *sweep.NULL_CONFIRM2_SEEDS}
    assert sweep.SHAPE_EVAL6_SEEDS == (401, 402, 403, 404, 405)
    assert sweep.NULL_CONFIRM4_SEEDS == tuple(range(14001, 14601))
    earlier = {*used, *SHAPE_DEV2_SEEDS, *SHAPE_EVAL_SEEDS, *SHAPE_EVAL2_SEEDS,
               *SHAPE_EVAL3_SEEDS, *SHAPE_EVAL4_SEEDS, *SHAPE_EVAL5_SEEDS,
               *sweep.NULL_EVAL_SEEDS, *sweep.NULL_DEV_SEEDS, *sweep.NULL_CONFIRM_SEEDS,
               *sweep.NULL_CONFIRM2_SEEDS, *sweep.NULL_CONFIRM3_SEEDS}
    assert not set(sweep.SHAPE_EVAL6_SEEDS) & earlier
    assert not set(sweep.NULL_CONFIRM4_SEEDS) & {*earlier, *sweep.SHAPE_EVAL6_SEEDS}
    assert sweep.SHAPE_EVAL7_SEEDS == (421, 422, 423, 424, 425)
    assert sweep.NULL_CONFIRM5_SEEDS == tuple(range(16001, 16601))
    before7 = {*earlier, *sweep.SHAPE_EVAL6_SEEDS, *sweep.NULL_CONFIRM4_SEEDS}
    assert not set(sweep.SHAPE_EVAL7_SEEDS) & before7
    assert not set(sweep.NULL_CONFIRM5_SEEDS) & {*before7, *sweep.SHAPE_EVAL7_SEEDS}
    # rounds 6b to 15 (three sets for round 12, two each for rounds 13 to 15): each
    # round's shape set and null set, fixed before the round, overlap nothing fixed or used
    # before them (nor each other)
    before = before7
    for shapes, first, nulls, start in (
            ("SHAPE_EVAL8_SEEDS", 441, "NULL_CONFIRM6_SEEDS", 18001),
            ("SHAPE_EVAL9_SEEDS", 461, "NULL_CONFIRM7_SEEDS", 20001),
            ("SHAPE_EVAL10_SEEDS", 481, "NULL_CONFIRM8_SEEDS", 22001),
            ("SHAPE_EVAL11_SEEDS", 501, "NULL_CONFIRM9_SEEDS", 24001),
            ("SHAPE_EVAL12_SEEDS", 521, "NULL_CONFIRM10_SEEDS", 26001),
            ("SHAPE_EVAL13_SEEDS", 541, "NULL_CONFIRM11_SEEDS", 28001),
            ("SHAPE_EVAL14_SEEDS", 601, "NULL_CONFIRM12_SEEDS", 30001),
            ("SHAPE_EVAL15_SEEDS", 621, "NULL_CONFIRM13_SEEDS", 32001),
            ("SHAPE_EVAL16_SEEDS", 641, "NULL_CONFIRM14_SEEDS", 34001),
            ("SHAPE_EVAL17_SEEDS", 661, "NULL_CONFIRM15_SEEDS", 36001),
            ("SHAPE_EVAL18_SEEDS", 681, "NULL_CONFIRM16_SEEDS", 38001),
            ("SHAPE_EVAL19_SEEDS", 701, "NULL_CONFIRM17_SEEDS", 40001),
            ("SHAPE_EVAL20_SEEDS", 721, "NULL_CONFIRM18_SEEDS", 42001),
            ("SHAPE_EVAL21_SEEDS", 741, "NULL_CONFIRM19_SEEDS", 44001)):
        shape_set, null_set = getattr(sweep, shapes), getattr(sweep, nulls)
        assert shape_set == tuple(range(first, first + 5))
        assert null_set == tuple(range(start, start + 600))
        assert not set(shape_set) & before
        assert not set(null_set) & {*before, *shape_set}
        before = {*before, *shape_set, *null_set}
        if shapes == "SHAPE_EVAL13_SEEDS":  # the third shapes development set, fixed
            # after round 11, overlaps no evaluation or confirmation set
            assert sweep.SHAPE_DEV3_SEEDS == tuple(range(561, 581))
            assert not set(sweep.SHAPE_DEV3_SEEDS) & before
            before |= set(sweep.SHAPE_DEV3_SEEDS)  # and no later set overlaps it
        if shapes == "SHAPE_EVAL8_SEEDS":  # the 0.5 degC development nulls, fixed after
            # round 6b, overlap no evaluation or confirmation set
            assert not set(sweep.NULL_DEV2_SEEDS) & before
            before |= set(sweep.NULL_DEV2_SEEDS)
    assert sweep.NULL_CONFIRM3_SEEDS == tuple(range(12001, 12601))
    assert not set(sweep.NULL_CONFIRM3_SEEDS) & {
        *used, *SHAPE_DEV2_SEEDS, *SHAPE_EVAL5_SEEDS, *sweep.NULL_EVAL_SEEDS,
        *sweep.NULL_DEV_SEEDS, *sweep.NULL_CONFIRM_SEEDS, *sweep.NULL_CONFIRM2_SEEDS}


def test_periodic_t_by_hand() -> None:
    # A·sin(2π·T/P + φ): T = 5 °C, P = 20 °C, φ = 0 → A·sin(π/2) = A; T = 15 → −A;
    # T = 0, φ = π/6 → A/2
    p = {"amplitude_dps": 0.03, "period_c": 20.0, "phase_rad": 0.0}
    t = np.array([0.0, 1.0, 2.0])
    got = shape_bias("periodic_t", p, t, np.array([5.0, 15.0, 10.0]))
    assert got == pytest.approx([0.03, -0.03, 0.0], abs=1e-15)
    half = shape_bias("periodic_t", {**p, "phase_rad": math.pi / 6}, t[:1], np.array([0.0]))
    assert half == pytest.approx([0.015])


def test_saturating_and_abs_dt_by_hand() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    die = np.full(4, 25.0)
    g = np.array([-3.0, -1.5, 0.0, 6.0])
    sat = shape_bias("saturating_dt", {"amplitude_dps": 0.05, "scale_c": 1.5}, t, die, g)
    # tanh(−2) = −0.9640276, tanh(−1) = −0.7615942, tanh(4) = 0.9993293
    assert sat == pytest.approx([-0.04820138, -0.03807971, 0.0, 0.04996646], abs=1e-8)
    ab = shape_bias("abs_dt", {"slope_dps_per_c": -0.01}, t, die, g)
    assert ab == pytest.approx([-0.03, -0.015, 0.0, -0.06])  # same sign both ways
    with pytest.raises(ConfigError):
        shape_bias("abs_dt", {"slope_dps_per_c": 0.01}, t, die)


def test_stop_operator_with_a_width_per_step() -> None:
    # steps +1, +1, −1, −1 °C through widths 4, 4, 2, 2: h = 0, .5, 1, 0, −1
    h = stop_operator(np.array([0.0, 1.0, 2.0, 1.0, 0.0]), np.array([4.0, 4.0, 4.0, 2.0, 2.0]))
    assert h == pytest.approx([0.0, 0.5, 1.0, 0.0, -1.0])


def test_rate_hysteresis_width_grows_with_the_rate() -> None:
    # a ramp at 0.04 °C/s with w0 = 1 °C, r0 = 0.02 °C/s: w = 1·(1 + 2) = 3 °C, so h
    # rises by 2/3 per °C and saturates after 1.5 °C (37.5 s); a plain stop operator
    # of 1 °C saturates after 0.5 °C
    p = {"amplitude_dps": 0.04, "width_c": 1.0, "rate_c_per_s": 0.02}
    t = np.arange(0.0, 100.0, 0.5)
    die = 20.0 + 0.04 * t
    got = shape_bias("rate_hysteresis", p, t, die)
    assert got[t == 25.0] == pytest.approx(0.04 * (2.0 / 3.0) * 1.0)  # 1 °C travelled
    assert got[t == 50.0] == pytest.approx(0.04)
    wide = shape_bias("wide_hysteresis", {"amplitude_dps": 0.04, "width_c": 1.0}, t, die)
    assert wide[t == 12.5] == pytest.approx(0.04)


@pytest.mark.parametrize("name", ["periodic_t", "saturating_dt", "abs_dt", "rate_hysteresis"])
def test_new_shapes_reach_truth_and_rate_with_drawn_parameters(name: str) -> None:
    cfg = SynthConfig(duration_s=1200.0, rate_hz=10.0)
    plain, _ = variant_runs(cfg, n_runs=1, seed=SHAPE_DEV_SEEDS[0])
    shaped, truth = variant_runs(cfg, shapes={name: {}}, n_runs=1, seed=SHAPE_DEV_SEEDS[0])
    again, _ = variant_runs(cfg, shapes={name: {}}, n_runs=1, seed=SHAPE_DEV_SEEDS[0])
    run = plain[0]
    added = shape_bias(name, truth.shapes[name], run.time_s, run.extra["true_temperature_c"],
                       run.extra["true_delta_t_c"])
    assert np.ptp(added) > 0.005
    assert shaped[0].true_bias_dps["x"] - run.true_bias_dps["x"] == pytest.approx(added)
    assert np.array_equal(shaped[0].rates_dps["x"], again[0].rates_dps["x"])  # seeded


def test_support_span_takes_every_significant_monotone_run() -> None:
    knots = np.arange(12.0)
    # a sine of period 4 knots: monotone runs of 2 intervals, all significant
    values = np.sin(2 * np.pi * knots / 4.0 + 0.3)
    cov = np.eye(12) * 1e-6
    assert support_span(knots, values, cov) == (0.0, 11.0)
    # a step between knots 5 and 6, flat (noise-free) elsewhere: the step, padded by
    # one interval each side (the spline's resolution)
    step = np.where(knots > 5.0, 1.0, 0.0)
    assert support_span(knots, step, cov) == (4.0, 7.0)
    # the same with changes within the noise beside it: still the step alone
    noisy = step + np.array([0, 1, 0, -1, 0, 1, 0, 1, 0, -1, 0, 1]) * 1e-3
    assert support_span(knots, noisy, cov) == (4.0, 7.0)
    assert segments(np.array([0.0, 1.0, 1.0, 0.0, -1.0])) == [(0, 2), (2, 4)]


def test_a_wiggle_within_the_noise_is_not_a_turn() -> None:
    knots = np.arange(12.0)
    cov = np.eye(12) * 1e-6  # SE of a change between two knots: sqrt(2)·1e-3
    # a V (|x| about knot 4, 0.01 per interval) with a reversal of 1.2e-3 (z ≈ 0.85) on its
    # rising side and one of 2.4e-3 (z ≈ 1.7) at its end: five monotone runs; the first
    # reversal joins its neighbours, the end one is dropped: two runs, knots 0-4 and 4-9,
    # padded by one interval
    v = np.abs(knots - 4.0) * 0.01
    v[7] -= 0.0112  # knot 7 1.2e-3 below knot 6
    v[10] -= 0.0112  # knot 10 …
    v[11] = v[10] - 0.0012  # … and 11 below knot 9
    assert len(segments(v)) == 5
    assert significant_runs(v, cov) == [(0, 4), (4, 9)]
    assert support_span(knots, v, cov) == (0.0, 10.0)
    # a gentle but significant slope beside a steep drop is part of the structure
    # (a saturating response after the catalogued ΔT term: tanh(x) − a·x)
    sat = np.array([0.0, 0.01, 0.02, 0.03, 0.04, -0.06, -0.05, -0.04, -0.03, -0.02, -0.01, 0.0])
    assert significant_runs(sat, cov) == [(0, 4), (4, 5), (5, 11)]
    assert support_span(knots, sat, cov) == (0.0, 11.0)
    # nothing significant: the steepest run alone (knots 6-7, 2e-3 in one interval), padded
    flat = np.array([0, 1, 0, -1, 0, 1, 0, 2, 0, -1, 0, 1]) * 1e-3
    assert len(significant_runs(flat, cov)) == 1
    assert support_span(knots, flat, cov) == (5.0, 8.0)


CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0)  # the sweep's reference readout
DEV = SHAPE_DEV_SEEDS[0]


def _diagnosed(shape: str, seed: int = DEV, **given: float) -> tuple[Diagnosis, VariantTruth]:
    runs, truth = variant_runs(CFG, shapes={shape: dict(given)}, n_runs=4, seed=seed)
    return diagnose(runs, simulate=False), truth


@pytest.fixture(scope="module")
def periodic() -> tuple[Diagnosis, VariantTruth]:
    return _diagnosed("periodic_t")


def test_periodic_bias_is_unexplained_in_temperature_over_all_of_it(
    periodic: tuple[Diagnosis, VariantTruth],
) -> None:
    d, truth = periodic
    assert d.findings == ()
    (u,) = d.unexplained
    assert u.variable == "temperature_c" and u.gain > 1.5
    # the structure is everywhere in T: `where` is the data's whole range
    assert u.where == (u.knots[0], u.knots[-1])
    p = truth.shapes["periodic_t"]
    assert u.knots[-1] - u.knots[0] > p["period_c"]  # several half-periods inside
    # the correction follows the injected sine (up to the paper's T, T² terms)
    t = np.array(u.knots)
    injected = p["amplitude_dps"] * np.sin(2 * np.pi * t / p["period_c"] + p["phase_rad"])
    poly = np.vander(t - t.mean(), 3)
    rest = np.array(u.correction_dps) - poly @ np.linalg.lstsq(poly, u.correction_dps)[0]
    sine = injected - poly @ np.linalg.lstsq(poly, injected)[0]
    assert float(np.corrcoef(rest, sine)[0, 1]) > 0.8


def test_bias_step_where_holds_its_support_on_a_dev_seed() -> None:
    d, truth = _diagnosed("bias_step", at_c=30.0)
    (u,) = d.unexplained
    p = truth.shapes["bias_step"]
    low = max(u.knots[0], p["at_c"] - 2 * p["width_c"])
    high = min(u.knots[-1], p["at_c"] + 2 * p["width_c"])
    assert u.where[0] <= low and u.where[1] >= high
    assert u.steepest[0] <= p["at_c"] <= u.steepest[1]


def test_saturating_gradient_is_unexplained_in_delta_t() -> None:
    d, _ = _diagnosed("saturating_dt")
    assert d.findings == ()
    (u,) = d.unexplained
    assert u.variable == "delta_t_c" and u.gain > 1.5
    assert u.to_dict()["gain"] == u.gain  # reported with its held-out gain


def test_rate_dependent_hysteresis_is_named_hysteresis() -> None:
    d, truth = _diagnosed("rate_hysteresis")
    (f,) = d.findings
    assert f.effect == "hysteresis" and f.gain > 1.5
    true = truth.shapes["rate_hysteresis"]["amplitude_dps"]
    assert abs(f.params["amplitude_dps"] / true - 1.0) < 0.2


def test_a_structure_in_time_standing_in_for_a_left_out_hysteresis_is_not_reported() -> None:
    # round 5 dev seed 41 at the corner: the rate-dependent hysteresis is declared not
    # resolvable, and round 5 then named a structure in time over [1515, 5970] s (no time
    # effect is injected). With the left-out hysteresis in the replays' null, the spline in
    # time buys no more there than on the runs
    runs, _ = variant_runs(CORNER_CFG, shapes={"rate_hysteresis": {}}, n_runs=3, seed=41)
    d = diagnose(runs, simulate=False)
    assert d.unexplained == ()
    verdicts = {v.effect: v for v in d.not_resolvable}
    assert "hysteresis" in verdicts
    v = verdicts["unexplained:time_since_power_on_s"]
    assert "hysteresis (left out by a verdict above) included" in v.reason
    assert v.params["gain"] < 1.10 * v.params["null_gain"]


def test_abs_dt_is_unexplained_in_delta_t_and_makes_gradient_quadratic_redundant() -> None:
    # dev seed 34: until round 5 |ΔT| was named gradient² with the shape note; with the
    # spline's knot count chosen by BIC_eff a 5–8-knot spline in ΔT passes in its place
    d, _ = _diagnosed("abs_dt", seed=34)
    assert d.findings == ()
    (u,) = d.unexplained
    assert u.variable == "delta_t_c" and u.gain > 1.5
    assert "made gradient_quadratic redundant" in u.evidence


def test_abs_dt_named_gradient_quadratic_carries_the_shape_note() -> None:
    # round 5 dev seed 41 at the corner (1 °C / 1.3 s, 3 runs): |ΔT| is named gradient²
    # (the nearest catalogued form); the spline in ΔT in its place is better held out, so
    # the finding says the shape differs. (Seed 43, this test's device until round 12, is
    # now named unexplained in ΔT: the knot count chosen held out gains ×1.86.)
    runs, truth = variant_runs(CORNER_CFG, shapes={"abs_dt": {}}, n_runs=3, seed=41)
    d = diagnose(runs, simulate=False)
    (f,) = d.findings
    assert f.effect == "gradient_quadratic" and f.gain > 1.2
    assert "the shape differs" in f.shape and "same sign heating and cooling" in f.shape
    assert "not ΔT²" in f.shape
    assert f.to_dict()["shape_differs"] == f.shape
    assert any(n.startswith("gradient_quadratic: the shape differs") for n in d.notes)
    assert truth.shapes["abs_dt"]["slope_dps_per_c"] != 0.0


def test_abs_dt_named_in_time_states_that_delta_t_is_not_told_apart(
    sweep: ModuleType,
) -> None:
    # ninth evaluation set, seed 464 at the corner (a used set; the case round 9 answers):
    # every run repeats the profile, |ΔT| is named a structure in time (×1.44), and a spline
    # in ΔT in its place does nearly as well (×1.35): the diagnosis says which variable is
    # not resolvable, and the sweep counts the miss as declared, not as a false alarm
    row = sweep.run_case(sweep.CASES_BY_NAME["abs_dt"], sweep.CONDITIONS[3], 464)
    (named,) = [n for n in row["named"] if n["name"].startswith("unexplained:")]
    assert named["name"] == "unexplained:time_since_power_on_s"
    assert set(named["not_told_from"]) == {"delta_t_c"}
    assert named["gain"] / named["not_told_from"]["delta_t_c"] < 1.10
    assert row["missed"] == row["variable_unresolved"] == ["unexplained:delta_t_c"]
    assert row["missed_not_resolvable"] == ["unexplained:delta_t_c"]
    assert row["false_alarms"] == []


def test_catalogued_gradient_quadratic_carries_no_shape_note() -> None:
    runs, _ = variant_runs(SynthConfig(duration_s=6000.0, rate_hz=10.0,
                                       effects={"gradient_quadratic": {}}),
                           n_runs=4, seed=DEV)
    (f,) = diagnose(runs, simulate=False).findings
    assert f.effect == "gradient_quadratic" and f.shape == ""
    assert "shape_differs" not in f.to_dict()


def test_an_exact_gradient_quadratic_read_at_the_corner_gets_no_shape_note() -> None:
    # dev seed 3 at the corner: the catalogue's own c·ΔT² is injected, yet a spline in
    # the estimated ΔT in its place is ×1.037 better held out (errors in the variable
    # bend ΔT²); readout replays of ΔT² give ×1.045, so the shape is not resolvable
    runs, _ = variant_runs(replace(CORNER_CFG, effects={"gradient_quadratic": {}}),
                           n_runs=3, seed=3)
    d = diagnose(runs, simulate=False)
    (f,) = d.findings
    assert f.effect == "gradient_quadratic" and f.shape == ""
    (v,) = [v for v in d.not_resolvable if v.effect == "shape:gradient_quadratic"]
    assert "readout replays of the runs with c·ΔT² exactly" in v.reason
    # passed the plain check (×1.03 on half the runs), not the replays'
    assert 1.03 <= v.params["ratio"] < 1.03 * v.params["null_ratio"]
    assert v.params["improved_runs"] >= 2
    assert any("its shape is not resolvable at this readout" in n for n in d.notes)


def test_the_shape_note_describes_a_curve_in_delta_t_by_hand() -> None:
    from gyrotherm.analysis._shape_check import _gradient_shape

    knots = np.linspace(-6.0, 6.0, 25)
    sat = _gradient_shape(knots, 0.05 * np.tanh(knots / 1.5))
    # odd; slope over [4, 6] against [0, 2]: (tanh 4 − tanh 8/3) / (tanh 4/3) = 0.0098/0.8705
    assert "odd in ΔT" in sat and "it saturates" in sat and "is 1% of that" in sat
    # beyond a linear term, as the note sees it: tanh less its least-squares line turns back
    resid = 0.05 * np.tanh(knots / 1.5)
    resid = resid - knots * float(resid @ knots / (knots @ knots))
    turned = _gradient_shape(knots, resid)
    assert "odd in ΔT" in turned and "it saturates" in turned and "is -" in turned
    line = _gradient_shape(knots, 0.01 * knots)
    assert "odd in ΔT" in line and "is 100% of that" in line and "saturates" not in line
    even = _gradient_shape(knots, 0.01 * np.abs(knots))
    assert "even in ΔT" in even and "closest to |ΔT|^1" in even
