"""Held-out evaluation of the diagnosis' false alarms (issue 19, item 1).

EVAL_SEEDS are fixed here and in scripts/generalisation_sweep.py before any
result on them was seen; they are never used while developing
the guards (:mod:`gyrotherm.analysis._resolve`, :mod:`._null_replay`), which were
developed on DEV_SEEDS. The corner condition is the sweep's coarsest: 10 Hz,
1 °C / 1.3 s readout, 3 runs."""

from __future__ import annotations

import json
from dataclasses import replace
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._intervals import bootstrap_quantile, wilson
from gyrotherm.analysis._resolution import Resolution, placement, step_slope_per_s
from gyrotherm.analysis._unexplained import Unexplained
from gyrotherm.analysis.synth._variants import variant_runs

FIRST_EVAL_SEEDS = (101, 102, 103, 104, 105)
"""Fixed at commit ec6247e, run once at 7d58088 (docs/findings.md §6); development seeds since."""
EVAL_SEEDS = (201, 202, 203, 204, 205)
"""Fixed (the commit adding this line) before any result on them was seen."""
DEV_SEEDS = (1, 2, 3, 4, 5, 6, *FIRST_EVAL_SEEDS)
NULL_EVAL_SEEDS = tuple(range(5001, 5801))
"""Nothing injected at scale (``--seeds null-eval``): fixed (the commit adding this line)
before any result on them was seen; seed j at the sweep's condition j % 4."""
NULL_DEV_SEEDS = tuple(range(6001, 6101))
"""Development seeds for nothing injected at the corner (after the null-eval run)."""
NULL_CONFIRM_SEEDS = tuple(range(8001, 8601))
"""Fresh nulls for the change developed on NULL_DEV_SEEDS: fixed (the commit adding this
line) before any result on them was seen."""
NULL_CONFIRM2_SEEDS = tuple(range(10001, 10601))
"""Fresh nulls for round 4 (a structure sharper than the readout can place, reported when
it beats the readout replays): fixed (the commit adding this line) before any result."""
CORNER = 3
"""Index of the 1 °C / 1.3 s / 3-run condition in the sweep's CONDITIONS."""


def test_eval_seeds_are_disjoint_from_development_seeds(sweep: ModuleType) -> None:
    assert not set(EVAL_SEEDS) & set(DEV_SEEDS)
    assert sweep.EVAL_SEEDS == EVAL_SEEDS
    assert sweep.DEV_SEEDS == DEV_SEEDS
    assert sweep.FIRST_EVAL_SEEDS == FIRST_EVAL_SEEDS
    assert sweep.CONDITIONS[CORNER].lsb_c == 1.0 and sweep.CONDITIONS[CORNER].n_runs == 3


def test_null_eval_seeds_are_fresh_and_cover_every_condition_equally(sweep: ModuleType) -> None:
    assert sweep.NULL_EVAL_SEEDS == NULL_EVAL_SEEDS
    assert sweep.NULL_DEV_SEEDS == NULL_DEV_SEEDS
    assert sweep.NULL_CONFIRM_SEEDS == NULL_CONFIRM_SEEDS
    assert sweep.NULL_CONFIRM2_SEEDS == NULL_CONFIRM2_SEEDS
    sets = [set(DEV_SEEDS), set(EVAL_SEEDS), set(sweep.SHAPE_DEV_SEEDS),
            set(sweep.SHAPE_EVAL_SEEDS), set(NULL_EVAL_SEEDS), set(NULL_DEV_SEEDS),
            set(NULL_CONFIRM_SEEDS), set(NULL_CONFIRM2_SEEDS)]
    assert sum(map(len, sets)) == len(set().union(*sets))
    n = len(sweep.CONDITIONS)
    for seeds in (NULL_EVAL_SEEDS, NULL_CONFIRM_SEEDS, NULL_CONFIRM2_SEEDS):
        assert [len(seeds[i::n]) for i in range(n)] == [len(seeds) // n] * n


def test_wilson_interval() -> None:
    lo, hi = wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.161, abs=1e-3)
    lo, hi = wilson(10, 20)
    assert lo < 0.5 < hi and lo == pytest.approx(1.0 - hi)
    assert wilson(0, 0) == (0.0, 1.0)


def test_bootstrap_quantile_is_seeded_and_brackets_the_median() -> None:
    values = [0.01, 0.02, 0.03, 0.05, 0.08, 0.13, 0.21]
    first = bootstrap_quantile(values, 0.5, seed=3)
    assert first == bootstrap_quantile(values, 0.5, seed=3)
    med, lo, hi = first
    assert med == pytest.approx(0.05) and lo <= med <= hi


@pytest.mark.parametrize("seed", FIRST_EVAL_SEEDS)
def test_nothing_injected_at_the_corner_on_the_first_eval_set(
    sweep: ModuleType, seed: int
) -> None:
    """First eval set (run once at 7d58088, where seed 102 named an unexplained structure
    in ΔT; development seeds since): at 1 °C / 1.3 s with 3 runs and nothing injected, the
    diagnosis names no effect (what the readout produces is declared not resolvable)."""
    case = next(c for c in sweep.CASES if c.name == "none")
    row = sweep.run_case(case, sweep.CONDITIONS[CORNER], seed)
    assert row["false_alarms"] == []
    assert set(row["not_resolvable"]) <= {"thermal_lag", "hysteresis", "unexplained:delta_t_c"}


@pytest.mark.parametrize("seed", EVAL_SEEDS)
def test_nothing_injected_at_the_corner_names_nothing(sweep: ModuleType, seed: int) -> None:
    """Second eval set: at 1 °C / 1.3 s with 3 runs and nothing injected, the diagnosis
    names no effect (what the readout cannot support is declared not resolvable)."""
    case = next(c for c in sweep.CASES if c.name == "none")
    row = sweep.run_case(case, sweep.CONDITIONS[CORNER], seed)
    assert row["false_alarms"] == []


def test_the_readout_lag_is_a_distinct_verdict_in_the_json() -> None:
    """Dev seed 4 (the review's device): nothing injected, the selection picks a lag of
    ≈ 111 s (die lag 5 s); the report names it not resolvable at this readout, with the
    τ the readout alone produces, and not as a finding."""
    runs, truth = variant_runs(SynthConfig(duration_s=6000.0, readout_lsb_c=1.0,
                                           readout_period_s=1.3), n_runs=3, seed=4)
    assert truth.base.die_tau_s < 10.0
    doc = json.loads(json.dumps(diagnose(runs, simulate=False).to_dict()))
    assert doc["findings"] == []
    (verdict,) = doc["not_resolvable"]
    assert verdict["effect"] == "thermal_lag"
    assert verdict["verdict"] == "not resolvable at this readout"
    assert "readout alone" in verdict["reason"] and "LSB crossing" in verdict["reason"]
    assert verdict["params"]["tau_s"] > 50.0 and verdict["params"]["null_tau_s"] > 50.0


@pytest.mark.parametrize(("seed", "condition"), [(101, 0), (3, CORNER), (4, CORNER)])
def test_a_real_lag_is_still_found(sweep: ModuleType, seed: int, condition: int) -> None:
    """The guard does not suppress everything: an injected die lag (150–500 s) is named,
    at the reference readout (eval seed) and through the corner readout (dev seeds).
    At the corner the shape check's power may add that the lag's shape cannot be told from
    a saturating ΔT response there (round 7, a ``shape:`` verdict); that keeps the finding,
    and the lag itself is never left out."""
    case = next(c for c in sweep.CASES if c.name == "thermal_lag")
    row = sweep.run_case(case, sweep.CONDITIONS[condition], seed)
    assert row["found"] == ["thermal_lag"]
    assert row["parameter_errors"]["thermal_lag"] < 0.5
    assert [v for v in row["not_resolvable"] if v != "shape:thermal_lag"] == []
    if condition != CORNER:
        assert row["not_resolvable"] == []


def test_a_drift_next_to_an_undecayed_warmup_is_not_resolvable_in_these_runs() -> None:
    """Dev seed 3, logistic warm-up (flat to t½ ≈ 700 s), reference readout: the
    catalogue's exponential comes out with τ ≈ 1800 s and a drift makes up its tail;
    the runs (6000 s) have too little beyond 3τ to tell them apart, so the drift is a
    'not resolvable in these runs' verdict, not a finding."""
    runs, _ = variant_runs(SynthConfig(duration_s=6000.0), shapes={"logistic_warmup": {}},
                           n_runs=4, seed=3)
    d = diagnose(runs, simulate=False)
    assert "drift" not in {f.effect for f in d.findings}
    (verdict,) = [v for v in d.not_resolvable if v.effect == "drift"]
    assert verdict.verdict == "not resolvable in these runs"
    assert verdict.params["warmup_tau_s"] > verdict.params["duration_s"] / 6.0
    assert "3τ" in verdict.reason


def test_a_drift_next_to_a_short_warmup_is_still_found() -> None:
    """Dev seed 2: a warm-up of τ = 300 s and a drift, both injected: the warm-up has
    decayed within the first 900 s, so the drift is resolvable and named."""
    runs, truth = variant_runs(SynthConfig(duration_s=6000.0, effects={
        "warmup": {"tau_s": 300.0}, "drift": {}}), n_runs=4, seed=2)
    d = diagnose(runs, simulate=False)
    found = {f.effect: f.params for f in d.findings}
    assert {"warmup", "drift"} <= set(found)
    true = truth.base.effects["drift"]["slope_dps_per_h"]
    assert found["drift"]["slope_dps_per_h"] == pytest.approx(true, rel=0.3)
    assert d.not_resolvable == ()


def test_the_readout_resolution_of_each_variable() -> None:
    # a unit step inside a 61-point least-squares slope moves it by Σk/Σk² = 3/122 per s
    k = np.arange(-30, 31)
    assert step_slope_per_s(61) == pytest.approx(np.sum(k[k > 0]) / np.sum(k * k))
    spans = Resolution(lsb_c=1.0, tau_s=240.0, hold_s=1.3).spans()
    assert spans["delta_t_c"] == pytest.approx(240.0 * 3.0 / 122.0)  # 5.9 °C
    assert spans["temperature_c"] == 1.0 and spans["time_since_power_on_s"] == 1.3


def test_a_structure_in_delta_t_finer_than_one_code_is_not_resolvable() -> None:
    """Null dev seed 6058, nothing injected, corner readout: splines in time and in ΔT pass
    the search, but one 1 °C code moves the ΔT estimate by ≈ 6 °C, and readout replays
    without them give as much: verdicts of the replays, not findings. (Dev seed 102 showed
    this until round 5; with the spline's knot count chosen by BIC_eff its ΔT structure no
    longer passes the search at all.) Round 15: each structure's null holds the other, the
    one furthest below its null (time, ×1.19 against ×1.21) is left out first, and without
    it no structure in ΔT passes the search; until round 14 both were verdicts at once."""
    runs, _ = variant_runs(SynthConfig(duration_s=6000.0, readout_lsb_c=1.0,
                                       readout_period_s=1.3), n_runs=3, seed=6058)
    d = diagnose(runs, simulate=False)
    assert d.findings == () and d.unexplained == ()
    (v,) = [v for v in d.not_resolvable if v.effect.startswith("unexplained:")]
    assert v.effect == "unexplained:time_since_power_on_s"
    assert v.params["gain"] < 1.10 * v.params["null_gain"]
    assert v.to_dict()["verdict"] == "not resolvable at this readout"
    assert "readout alone" in v.reason
    assert "with the structure in delta_t_c found beside it" in v.reason


def test_placement_note_by_hand() -> None:
    """A structure whose steepest span is narrower than one readout step of its variable
    is placed no finer than that step: ΔT at 1 °C, τ 240 s: 240·3/122 = 5.90 °C."""
    res = Resolution(lsb_c=1.0, tau_s=240.0, hold_s=1.3)
    narrow = Unexplained("delta_t_c", (-8.0, 8.0), (-8.0, 0.0, 8.0), (0.0, 0.0, 0.0),
                         0.01, 1.4, "", steepest=(-1.0, 2.0))
    note = placement(narrow, res)
    assert note is not None and "[-1, 2] (span 3)" in note and "5.9 " in note
    assert placement(replace(narrow, steepest=(-3.0, 3.0)), res) is None  # 6 > 5.90
    t_step = replace(narrow, variable="temperature_c", steepest=(29.6, 30.4))
    assert placement(t_step, res) is not None  # 0.8 °C < one 1 °C code
    assert placement(t_step, replace(res, lsb_c=0.125)) is None


def test_a_saturating_gradient_sharper_than_the_corner_shows_is_reported(
    sweep: ModuleType,
) -> None:
    """Shape dev seed 33, saturating ΔT response (tanh, s = 1–2 °C) at the corner, where
    one code moves the ΔT estimate by ≈ 6 °C: its steepest part is narrower than that,
    but it beats the readout replays, so it is an unexplained ΔT finding (held-out gain
    above the selection's ×1.10), with a note that the readout cannot place it finer when
    the spline's steepest span is narrower than one code (the note by hand:
    test_placement_note_by_hand); before round 4 it was a verdict and a miss."""
    cond = sweep.CONDITIONS[CORNER]
    cfg = SynthConfig(duration_s=sweep.DURATION_S, rate_hz=cond.rate_hz,
                      readout_lsb_c=cond.lsb_c, readout_period_s=cond.period_s)
    runs, truth = variant_runs(cfg, shapes={"saturating_dt": {}}, n_runs=cond.n_runs, seed=33)
    d = diagnose(runs, simulate=False)
    (u,) = [u for u in d.unexplained if u.variable == "delta_t_c"]
    assert u.gain > 1.10
    assert 2.0 * truth.shapes["saturating_dt"]["scale_c"] < 5.9  # sharper than one code
    # the note goes with the steepest span the spline shows: since round 5 its knot count
    # is chosen by BIC_eff (6 here, 3 °C apart), which can show the span wider than the
    # true one; the note is then absent, and the finding stands
    narrow = u.steepest[1] - u.steepest[0] < 5.9
    assert ("narrower than the readout can place" in u.evidence) == narrow
    assert any(n.startswith("unexplained:delta_t_c: its steepest part")
               for n in d.notes) == narrow
    assert "unexplained:delta_t_c" not in {v.effect for v in d.not_resolvable}


def _corner_null(seed: int) -> dict[str, Any]:
    runs, _ = variant_runs(SynthConfig(duration_s=6000.0, readout_lsb_c=1.0,
                                       readout_period_s=1.3), n_runs=3, seed=seed)
    doc: dict[str, Any] = json.loads(json.dumps(diagnose(runs, simulate=False).to_dict()))
    return doc


def test_a_structure_in_time_the_readout_alone_produces_is_not_resolvable() -> None:
    """Null dev seed 6006 at the corner: a spline in time since power-on passed (×1.13,
    better on 3/3 left-out runs): what the T and ΔT terms leave of the staircase follows
    the profile, which every run repeats at the same times. Readout replays of the model
    without it give a spline ×1.10, so it is a verdict, not a finding."""
    doc = _corner_null(6006)
    assert doc["findings"] == []
    verdicts = {v["effect"]: v for v in doc["not_resolvable"]}
    v = verdicts["unexplained:time_since_power_on_s"]
    assert v["verdict"] == "not resolvable at this readout"
    assert v["params"]["gain"] < 1.10 * v["params"]["null_gain"]
    assert "readout alone" in v["reason"]


def test_an_effect_selected_beside_an_unresolvable_lag_must_still_earn_its_place() -> None:
    """Null dev seed 6031 at the corner: the selection took a lag (τ 94 s, the readout's)
    and a gradient²; the lag is not resolvable, and without it the gradient² buys ×1.02:
    dropped, with a note, instead of reported."""
    doc = _corner_null(6031)
    assert doc["findings"] == []
    assert [v["effect"] for v in doc["not_resolvable"]] == ["thermal_lag"]
    assert any("gradient_quadratic" in n and "no longer earns its place"
               in n for n in doc["notes"])
