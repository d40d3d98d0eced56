"""A drift beside a warm-up against a second warm-up time constant in its place
(:func:`gyrotherm.analysis._separable.drop_drift_like_second_warmup`), and a drift against
the runs' settled holds (:func:`~gyrotherm.analysis._separable.drop_drift_not_in_holds`), on
the generator's truth: the slow part of a two-exponential warm-up is not a drift, nor is
what a rate-dependent hysteresis' misfit leaves in time; a real drift (it goes on for the
whole run, through holds) is kept. Development seeds only (SHAPE_DEV2_SEEDS, DEV_SEEDS)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._separable import (
    HOLD_MIN_S,
    HOLD_SETTLE_S,
    RUNS_VERDICT,
    SECOND_WARMUP_VERDICT,
    _holds,
    drop_drift_like_second_warmup,
    drop_drift_not_in_holds,
)
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.codecs import Run

from .conftest import CORNER_CFG, prepared_selector

CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0, readout_lsb_c=0.125, readout_period_s=1.28)


def _selector(runs: Sequence[Run]) -> Selector:
    return prepared_selector(runs)[0]


def _warmup_and_drift(sel: Selector) -> Mapping[str, float]:
    return sel.evaluate({"warmup": 0.0, "drift": 0.0}, search="warmup").effects


@pytest.mark.parametrize("seed", [41, 42])
def test_the_slow_part_of_a_two_exponential_warmup_is_not_a_drift(seed: int) -> None:
    runs, truth = variant_runs(CFG, shapes={"two_exp_warmup": {}}, n_runs=4, seed=seed)
    sel = _selector(runs)
    final = sel.evaluate(dict(_warmup_and_drift(sel)))
    kept, verdict, note = drop_drift_like_second_warmup(sel, final)
    assert "drift" not in kept.effects and "warmup" in kept.effects
    assert verdict is not None and verdict.verdict == SECOND_WARMUP_VERDICT
    assert verdict.params["ratio"] >= 1.0
    # the two time constants found are the injected ones, within the warm-up's coarse grid
    # steps (×1.6) and their trade-off (the forced fit's single τ lies between them)
    shape = truth.shapes["two_exp_warmup"]
    assert shape["tau_1_s"] / 1.6 < verdict.params["first_tau_s"] < 1.6 * shape["tau_1_s"]
    assert shape["tau_2_s"] / 1.6 < verdict.params["second_tau_s"] < 1.6 * shape["tau_2_s"]
    assert verdict.params["first_tau_s"] < verdict.params["warmup_tau_s"]
    assert note is not None and "second time constant" in note


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_a_real_drift_beside_a_warmup_is_kept(seed: int) -> None:
    """Dev seeds: a warm-up (τ 200–900 s) and a drift, both injected: the drift goes on
    where a second exponential would flatten."""
    runs, _ = variant_runs(SynthConfig(duration_s=6000.0, effects={
        "warmup": {}, "drift": {}}), n_runs=4, seed=seed)
    sel = _selector(runs)
    final = sel.evaluate(dict(_warmup_and_drift(sel)))
    kept, verdict, note = drop_drift_like_second_warmup(sel, final)
    assert kept is final and verdict is None and note is None


def test_nothing_to_weigh_without_both() -> None:
    runs, _ = variant_runs(CFG, shapes={"two_exp_warmup": {}}, n_runs=4, seed=41)
    sel = _selector(runs)
    final = sel.evaluate({"warmup": 0.0}, search="warmup")
    assert drop_drift_like_second_warmup(sel, final) == (final, None, None)


def test_holds_by_hand() -> None:
    """1-s blocks: a ramp, a 1500-s hold, a ramp, a 600-s hold (too short), a ramp, a hold
    to the end (1000 s): the settled parts are the long holds after their first 600 s."""
    rate = np.concatenate([np.full(500, 0.05), np.zeros(1500), np.full(500, -0.05),
                           np.zeros(600), np.full(400, 0.05), np.zeros(1000)])
    t = np.arange(len(rate), dtype=float)
    got = _holds(t, rate)
    assert len(got) == 2
    for idx, (start, length) in zip(got, [(500, 1500), (3500, 1000)], strict=True):
        # the 121-s average blurs each edge by 60 blocks
        assert abs(t[idx[0]] - (start + HOLD_SETTLE_S)) <= 61
        assert abs(t[idx[-1]] - (start + length - 1)) <= 61
    assert HOLD_MIN_S > 600.0


HALF = SynthConfig(duration_s=6000.0, rate_hz=50.0, readout_lsb_c=0.5, readout_period_s=1.0)


@pytest.mark.parametrize(("cfg", "n_runs", "seed"), [(CFG, 4, 1), (HALF, 3, 4), (CORNER_CFG, 3, 1)])
def test_a_real_drift_shows_in_the_holds(cfg: SynthConfig, n_runs: int, seed: int) -> None:
    runs, _ = variant_runs(replace(cfg, effects={"drift": {}}), n_runs=n_runs, seed=seed)
    sel = _selector(runs)
    final = sel.evaluate({"drift": 0.0})
    kept, verdict = drop_drift_not_in_holds(sel, final)
    assert kept is final and verdict is None


def test_a_drift_beside_a_rate_dependent_hysteresis_is_not_in_the_holds() -> None:
    """shapes-dev2 seed 45 at 0.5 °C: the selection names a hysteresis and a drift; the
    holds trend the other way (the drift's slope 3.3 standard errors from theirs)."""
    runs, truth = variant_runs(HALF, shapes={"rate_hysteresis": {}}, n_runs=3, seed=45)
    d = diagnose(runs, simulate=False)
    assert {"hysteresis", "drift"} <= set(d.selection.final.effects)
    assert {f.effect for f in d.findings} == {"hysteresis"}
    (verdict,) = [v for v in d.not_resolvable if v.effect == "drift"]
    assert verdict.verdict == RUNS_VERDICT and "settled holds" in verdict.reason
    p = verdict.params
    assert p["hold_slope_dps_per_h"] * p["slope_dps_per_h"] < 0.0  # the holds disagree
    assert abs(p["slope_dps_per_h"] - p["hold_slope_dps_per_h"]) >= 2.0 * p[
        "hold_slope_se_dps_per_h"]
    assert truth.shapes["rate_hysteresis"]["amplitude_dps"] != 0.0
