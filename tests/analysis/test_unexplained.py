"""Unexplained residual structure: an off-catalogue effect (a smooth bias step at a
temperature, from the independent generator's variants) is reported as
``unexplained`` on temperature_c where the step is, not forced into a catalogued
name; clean data and catalogued effects give no unexplained finding. Seeds fixed
before any result was seen."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.analysis import Diagnosis, SynthConfig, diagnose
from gyrotherm.analysis._diagnose import export_calibration
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._report import _where_line
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._select import _compare
from gyrotherm.analysis._unexplained import (
    KNOT_COUNTS,
    N_KNOTS,
    Search,
    evaluate_with,
    hats,
    knots_for,
    search_unexplained,
    spline_knots,
    steepest_span,
)
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling

from .conftest import CORNER_CFG

CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0)
STEP_C = 30.0


def test_hats_interpolate_linearly_and_hold_beyond_the_knots() -> None:
    knots = np.array([0.0, 1.0, 2.0])
    b = hats(np.array([-1.0, 0.5, 1.5, 3.0]), knots)
    assert b == pytest.approx(np.array([[1, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0.5], [0, 0, 1]]))
    # partition of unity and linear reproduction (clipped to the knot range)
    v = np.linspace(-0.5, 2.5, 31)
    assert hats(v, knots).sum(axis=1) == pytest.approx(np.ones(31))
    assert hats(v, knots) @ knots == pytest.approx(np.clip(v, 0.0, 2.0))


def test_steepest_span_takes_the_neighbours_at_least_half_as_steep() -> None:
    # slopes 0, 1, 0.6, 0: the steepest interval [1, 2] and its neighbour [2, 3]
    span = steepest_span(np.arange(5.0), np.array([0.0, 0.0, 1.0, 1.6, 1.6]))
    assert span == (1.0, 3.0)


@pytest.fixture(scope="module")
def step_runs() -> tuple[list[Run], dict[str, float], Diagnosis]:
    runs, truth = variant_runs(CFG, shapes={"bias_step": {"at_c": STEP_C}}, n_runs=4, seed=11)
    return runs, dict(truth.shapes["bias_step"]), diagnose(runs, simulate=False)


def test_bias_step_is_unexplained_on_temperature_where_the_step_is(
    step_runs: tuple[list[Run], dict[str, float], Diagnosis],
) -> None:
    _, step, d = step_runs
    assert d.findings == ()  # no catalogued name forced onto it
    (u,) = d.unexplained
    data = d.to_dict()["findings"]
    assert [f["effect"] for f in data] == ["unexplained"]
    assert data[0]["params"]["variable"] == "temperature_c"
    low, high = data[0]["params"]["where"]
    knots = np.array(u.knots)
    # `where` holds the step's whole support within the data's range, T0 ± 2w
    assert low <= max(knots[0], STEP_C - 2 * step["width_c"])
    assert high >= min(knots[-1], STEP_C + 2 * step["width_c"])
    # `steepest`, where it changes fastest, is a place, not the whole range
    low, high = data[0]["params"]["steepest"]
    assert low <= STEP_C <= high
    assert high - low < 15.0  # runs span ≥ 30 °C
    assert data[0]["gain"] > 1.1
    # the correction rises (falls) across `steepest` as the injected step does
    values = np.array(u.correction_dps)
    change = float(np.interp(high, knots, values) - np.interp(low, knots, values))
    assert np.sign(change) == np.sign(step["amplitude_dps"])
    assert 0.3 * abs(step["amplitude_dps"]) < abs(change) < 1.5 * abs(step["amplitude_dps"])


def test_calibration_deploys_the_unexplained_correction_and_records_it(
    step_runs: tuple[list[Run], dict[str, float], Diagnosis],
) -> None:
    runs, step, d = step_runs
    cal = export_calibration(runs, d).calibration
    assert cal.effect_names("x") == ("correction",)
    assert cal.effect_names("y") == cal.effect_names("z") == ()
    corr = cal.effects_of("x").correction
    assert corr is not None and corr.variable == "temperature_c"
    assert corr.knots[0] < STEP_C < corr.knots[-1]
    # the deployed spline steps across the injected step, by about its size
    change = corr.value(STEP_C + 3 * step["width_c"]) - corr.value(STEP_C - 3 * step["width_c"])
    assert 0.5 * abs(step["amplitude_dps"]) < abs(change) < 1.5 * abs(step["amplitude_dps"])
    assert np.sign(change) == np.sign(step["amplitude_dps"])
    (deployed,) = cal.provenance["diagnosis"]["deployed"]
    assert deployed["params"]["variable"] == "temperature_c"
    assert cal.provenance["diagnosis"]["not_deployed"] == []
    record = cal.provenance["effects_fit"]["x"]["correction"]
    assert record["gain"] > 1.1  # held out, on the vehicle's features
    assert record["range"] == [corr.knots[0], corr.knots[-1]]


@pytest.mark.parametrize(("effects", "seed"), [
    ({}, 3),
    ({}, 104),
    ({"hysteresis": {}}, 101),
    ({"cubic": {}}, 207),
    ({"warmup": {}}, 101),
])
def test_no_unexplained_finding_on_clean_data_or_catalogued_effects(
    effects: dict[str, dict[str, float]], seed: int
) -> None:
    runs, _ = variant_runs(replace(CFG, effects=effects), n_runs=4, seed=seed)
    d = diagnose(runs, simulate=False)
    assert d.unexplained == ()
    assert {f.effect for f in d.findings} == set(effects)


def test_the_knot_count_is_chosen_by_bic_and_deployed_as_found() -> None:
    """Round 5 development seed 43 (SHAPE_DEV2_SEEDS), a periodic bias in T through the
    corner readout (1 °C / 1.3 s, 3 runs): with 12 knots the spline's ΔBIC_eff is not
    negative (the blocks' residuals are correlated over minutes), with fewer it is, at a
    held-out gain well above ×1.10; the search reports it with the knots BIC_eff chose,
    over the whole range (a periodic bias spans it), and the calibration deploys that many
    knots."""
    runs, _ = variant_runs(CORNER_CFG, shapes={"periodic_t": {}}, n_runs=3, seed=43)
    d = diagnose(runs, simulate=False)
    (u,) = d.unexplained
    assert u.variable == "temperature_c" and u.gain > 1.10
    assert len(u.knots) < N_KNOTS
    t = np.concatenate([p.temperature_c for p in d.prepared])
    lo, hi = np.percentile(t, [0.5, 99.5])
    assert u.where[0] <= lo + 0.1 * (hi - lo) and u.where[1] >= hi - 0.1 * (hi - lo)
    # why: 12 knots do not pass ΔBIC_eff on the paper model, the chosen count does
    sel = Selector(list(d.prepared), Scaling.from_data(
        t, np.concatenate([p.delta_t_c for p in d.prepared])))
    paper = evaluate_with(sel, {}, [])
    twelve = evaluate_with(sel, {}, [("temperature_c", knots_for(sel.runs, "temperature_c"))])
    chosen = spline_knots(sel, dict(d.extended.effects), [], "temperature_c")
    fewer = evaluate_with(sel, {}, [("temperature_c", chosen)])
    assert _compare(paper, twelve)[2] >= 0.0 > _compare(paper, fewer)[2]
    assert len(chosen) == len(u.knots)
    cal = export_calibration(runs, d).calibration
    corr = cal.effects_of("x").correction
    assert corr is not None and len(corr.knots) == len(u.knots)


HALF_CFG = SynthConfig(duration_s=6000.0, rate_hz=50.0, readout_lsb_c=0.5,
                       readout_period_s=1.0)
"""The sweep's 50 Hz, 0.5 °C / 1.0 s readout, diagnosed on 3 runs."""


def test_the_knot_count_is_the_best_held_out_of_those_bic_supports() -> None:
    """Round 12 of issue 19: the thirteenth evaluation set's seed 542 (used: scored on the
    round-11 method, a plain miss, kept as a regression test), a periodic bias in T of
    15 °C period and 0.021 °/s through the 0.5 °C readout (oracle ×1.59). ΔBIC_eff is
    lowest at 8 knots, which gain only ×1.09 held out (below ×1.10); 12 knots also have
    ΔBIC_eff < 0 and gain ×1.20 on 3/3 left-out runs. The rule takes 12, and the diagnosis
    names the structure in T over the whole range (the first rule named nothing)."""
    shape = {"periodic_t": {}}
    runs, truth = variant_runs(HALF_CFG, shapes=shape, n_runs=3, seed=542)
    assert truth.shapes["periodic_t"]["period_c"] == pytest.approx(15.02, abs=0.01)
    d = diagnose(runs, simulate=False)
    t = np.concatenate([p.temperature_c for p in d.prepared])
    sel = Selector(list(d.prepared), Scaling.from_data(
        t, np.concatenate([p.delta_t_c for p in d.prepared])))
    paper = evaluate_with(sel, {}, [])
    by_count = {n: _compare(paper, evaluate_with(
        sel, {}, [("temperature_c", knots_for(sel.runs, "temperature_c", n))]))
        for n in KNOT_COUNTS}
    supported = {n: c for n, c in by_count.items() if c[2] < 0.0}
    assert min(by_count, key=lambda n: by_count[n][2]) == 8  # the old rule's choice
    assert by_count[8][0] < 1.10 <= by_count[12][0] and 12 in supported
    chosen = spline_knots(sel, {}, [], "temperature_c")
    assert len(chosen) == max(supported, key=lambda n: supported[n][0]) == 12
    (u,) = d.unexplained
    assert u.variable == "temperature_c" and len(u.knots) == 12 and u.gain > 1.10
    lo, hi = np.percentile(t, [0.5, 99.5])
    assert u.where[0] <= lo + 0.1 * (hi - lo) and u.where[1] >= hi - 0.1 * (hi - lo)
    assert not d.findings  # nothing catalogued stands in for it


def _ramp_runs(holds_s: list[float], flips: list[float], seed: int,
               warmup_dps: float = 0.0, dt_error_c: float = 0.15) -> list[Prepared]:
    """3000-s runs: a hold of ``holds_s[r]`` at 25 °C, a smooth (raised-cosine) ramp of
    flip·15 °C over 1000 s, a hold, the ramp back, a hold to the end. The bias is
    0.03·|G|, G = 120·dT/dt the true gradient (even in it, which the paper's terms cannot
    follow), plus white noise σ = 0.003 °/s; the runs' ΔT estimate is G plus an error of
    σ = ``dt_error_c`` (0.15 °C: a coarse readout's). ``warmup_dps``: a second structure,
    a warm-up of that size, exp(−t/400 s); ramps of 15·|flip| °C."""
    rng = np.random.default_rng(seed)
    t = np.arange(3000.0)
    out = []
    for r, (hold, flip) in enumerate(zip(holds_s, flips, strict=True)):
        up = np.clip((t - hold) / 1000.0, 0.0, 1.0)
        down = np.clip((t - hold - 1500.0) / 1000.0, 0.0, 1.0)
        temp = 25.0 + flip * 7.5 * (np.cos(np.pi * down) - np.cos(np.pi * up))
        g = 120.0 * np.gradient(temp)
        rate = (0.001 * temp + 0.03 * np.abs(g) + warmup_dps * np.exp(-t / 400.0)
                + 0.003 * rng.standard_normal(len(t)))
        dt = g + dt_error_c * rng.standard_normal(len(t))
        out.append(Prepared(name=f"r{r}", time_s=t, temperature_c=temp, rate_c_per_s=g / 120,
                            delta_t_c=dt, chamber_c=None, rate_dps=rate,
                            counts=np.ones(len(t)), direction=np.zeros(len(t))))
    return out


def _search(runs: list[Prepared]) -> Search:
    sel = Selector(runs, Scaling.from_data(np.concatenate([p.temperature_c for p in runs]),
                                           np.concatenate([p.delta_t_c for p in runs])))
    return search_unexplained(sel, sel.evaluate({}), margin=0.10)


def test_a_structure_is_not_told_apart_from_a_variable_the_runs_move_with_it() -> None:
    # every run the same profile, its ramps mirror images: |G| is the same function of T
    # on every run (and of time). With the ΔT estimate's error of a coarse readout
    # (σ = 0.3 °C) a spline in T does as well as one in ΔT, and whichever is reported lists
    # the other as not told apart (within the margin)
    (u,) = _search(_ramp_runs([300.0, 300.0, 300.0], [1.0, 1.0, 1.0], seed=5,
                              dt_error_c=0.3)).unexplained
    assert u.gain > 1.5
    assert {u.variable, *u.not_told_from} >= {"delta_t_c", "temperature_c"}
    assert all(u.gain / g < 1.10 for g in u.not_told_from.values())  # within the margin
    assert "not resolvable at this readout" in u.evidence
    assert u.to_dict()["params"]["not_told_from"] == dict(u.not_told_from)
    # with σ = 0.15 °C the ΔT spline, at the knot count chosen held out (12; round 12),
    # gains ×2.27 against T's ×1.80: beyond the margin, so the runs do tell them apart
    (v,) = _search(_ramp_runs([300.0, 300.0, 300.0], [1.0, 1.0, 1.0], seed=5)).unexplained
    assert v.variable == "delta_t_c" and len(v.knots) == 12 and v.not_told_from == {}


def test_a_structure_the_runs_tell_apart_names_its_variable_alone() -> None:
    # ramps at different times and in both directions: |ΔT| is no function of time or T
    (u,) = _search(_ramp_runs([0.0, 250.0, 500.0], [1.0, -1.0, 1.0], seed=5)).unexplained
    assert u.variable == "delta_t_c"
    assert u.not_told_from == {}
    assert "not told apart" not in u.evidence


def test_two_structures_the_runs_tell_apart_list_no_rival() -> None:
    # one structure in ΔT and one in time (a warm-up), on runs that tell the variables
    # apart: both found, T listed as a rival of neither, and each one's gain is over the
    # final model (the other structure in it), the basis its rivals are tried on
    runs = _ramp_runs([0.0, 250.0, 500.0], [0.7, 1.0, 1.3], seed=5, warmup_dps=0.1)
    found = _search(runs).unexplained
    assert {u.variable for u in found} == {"delta_t_c", "time_since_power_on_s"}
    assert all(u.not_told_from == {} for u in found)
    sel = Selector(runs, Scaling.from_data(np.concatenate([p.temperature_c for p in runs]),
                                           np.concatenate([p.delta_t_c for p in runs])))
    for u in found:
        (other,) = [(w.variable, np.array(w.knots)) for w in found if w is not u]
        without = evaluate_with(sel, {}, [other])
        with_it = evaluate_with(sel, {}, [other, (u.variable, np.array(u.knots))])
        assert u.gain == pytest.approx(without.heldout_rms_dps / with_it.heldout_rms_dps)
        assert u.heldout_rms_dps == pytest.approx(with_it.heldout_rms_dps)


def test_a_deployed_correction_not_told_apart_says_so() -> None:
    # the ninth evaluation set's |ΔT| at the corner (seed 464, a used set): named in time,
    # ΔT not told apart; the calibration still deploys it, with the caveat said and kept
    runs, _ = variant_runs(CORNER_CFG, shapes={"abs_dt": {}}, n_runs=3, seed=464)
    d = diagnose(runs, simulate=False)
    (u,) = d.unexplained
    assert u.variable == "time_since_power_on_s" and set(u.not_told_from) == {"delta_t_c"}
    said: list[str] = []
    cal = export_calibration(runs, d, progress=said.append).calibration
    assert any("not told apart from a structure in delta_t_c" in m for m in said)
    (deployed,) = cal.provenance["diagnosis"]["deployed"]
    assert deployed["params"]["not_told_from"] == dict(u.not_told_from)


def test_report_says_where_the_structure_changes_against_the_data_range(
    step_runs: tuple[list[Run], dict[str, float], Diagnosis],
) -> None:
    (u,) = step_runs[2].unexplained
    k0, k1 = u.knots[0], u.knots[-1]
    whole = _where_line(replace(u, where=(k0, k1)))
    assert whole.endswith("(all of it)") and f"{k0:.4g}" in whole
    part = _where_line(replace(u, where=(u.knots[2], k1)))
    assert f"[{u.knots[2]:.4g}, {k1:.4g}] of the data's [{k0:.4g}, {k1:.4g}]" in part
    assert "within the noise" in part and "all of it" not in part
