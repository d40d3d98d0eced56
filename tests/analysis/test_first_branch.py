"""A warm-up beside a hysteresis against the hysteresis' first branch
(:mod:`gyrotherm.analysis._first_branch`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._first_branch import FIRST_BRANCH_VERDICT, first_branch
from gyrotherm.analysis.synth._variants import variant_runs

FINE = SynthConfig(duration_s=6000.0, rate_hz=10.0)  # the sweep's 0.125 °C / 1.28 s readout


def test_first_branch_by_hand() -> None:
    # width 1 °C: the catalogued state turns at 21.5 °C (1.5 above the low; 21.0 is only
    # 1.0 above it); before, the branch follows (T − 20)/1; after, it relaxes from 1.0 by
    # e^(−travel/1) with travel 0, 0.5, 1.5, 2.5 °C
    t = np.array([20.0, 20.5, 21.0, 21.5, 22.0, 21.0, 20.0])
    expected = [0.0, 0.5, 1.0, 1.0, math.exp(-0.5), math.exp(-1.5), math.exp(-2.5)]
    assert first_branch(t, 1.0) == pytest.approx(expected)
    # clipped at ±1 before the turn; all zero for a temperature that never moves
    assert first_branch(np.array([20.0, 19.5, 18.0, 18.0]), 2.5)[:3] == pytest.approx(
        [0.0, -0.2, -0.8])
    assert not first_branch(np.full(5, 25.0), 1.0).any()
    assert len(first_branch(np.array([]), 1.0)) == 0


def test_a_warmup_standing_in_for_the_first_branch_is_a_verdict() -> None:
    # shapes-dev2 seed 46 at 0.125 °C: a rate-dependent hysteresis (a stop operator that
    # moves from power-on), no warm-up injected; round 6 named a warm-up ×1.085 beside it
    runs, truth = variant_runs(FINE, shapes={"rate_hysteresis": {}}, n_runs=4, seed=46)
    assert set(truth.shapes) == {"rate_hysteresis"}
    d = diagnose(runs, simulate=False)
    assert [f.effect for f in d.findings] == ["hysteresis"]
    (v,) = [v for v in d.not_resolvable if v.effect == "warmup"]
    assert v.verdict == FIRST_BRANCH_VERDICT and v.params["ratio"] >= 1.0
    assert "first branch" in v.reason


@pytest.mark.parametrize("seed", [1, 2])
def test_a_real_warmup_beside_a_real_hysteresis_is_kept(seed: int) -> None:
    # dev seeds: both injected in the catalogue's formulas; the warm-up beats the first
    # branch by ×2 or more held out, so it stays a finding
    runs, truth = variant_runs(
        SynthConfig(duration_s=6000.0, rate_hz=10.0,
                    effects={"warmup": {}, "hysteresis": {}}), n_runs=4, seed=seed)
    d = diagnose(runs, simulate=False)
    found = {f.effect: f for f in d.findings}
    assert {"warmup", "hysteresis"} <= set(found)
    assert not any(v.verdict == FIRST_BRANCH_VERDICT for v in d.not_resolvable)
    true_a = truth.base.effects["warmup"]["amplitude_dps"]
    assert abs(found["warmup"].params["amplitude_dps"] / true_a - 1.0) < 0.3
