"""A drift beside a warm-up against a second warm-up time constant in its place
(:func:`gyrotherm.analysis._separable.drop_drift_like_second_warmup`), on the generator's
truth: the slow part of a two-exponential warm-up is not a drift; a real drift (it goes on
for the whole run) is kept. Development seeds only (SHAPE_DEV2_SEEDS, DEV_SEEDS)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis._prep import characterise, estimator_for, fit_tau, prepare, with_tau
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._separable import SECOND_WARMUP_VERDICT, drop_drift_like_second_warmup
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling

CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0, readout_lsb_c=0.125, readout_period_s=1.28)


def _selector(runs: Sequence[Run]) -> Selector:
    readouts = [characterise(r, "x") for r in runs]
    est = estimator_for(readouts)
    prepared = [prepare(r, "x", est) for r in runs]
    tau = fit_tau(prepared)
    assert tau is not None
    prepared = [with_tau(p, tau[0]) for p in prepared]
    return Selector(prepared, Scaling.from_data(
        np.concatenate([p.temperature_c for p in prepared]),
        np.concatenate([p.delta_t_c for p in prepared])))


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
