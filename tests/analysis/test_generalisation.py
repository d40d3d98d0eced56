"""Generalisation: the off-catalogue generator shapes are what they claim, the
diagnosis knows which thermal lag its temperature readout can resolve (a real lag
above the limit is found; a lag the coarse readout alone produces is not named),
and a slice of scripts/generalisation_sweep.py scores found / false alarms against
the injected truth. Seeds fixed before any result was seen."""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._prep import Prepared, Readout
from gyrotherm.analysis._resolve import LagLimit, drop_unresolved_lag, lag_limit
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis.synth._variants import shape_bias, stop_operator, variant_runs
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling

COARSE = SynthConfig(duration_s=6000.0, readout_lsb_c=1.0, readout_period_s=1.3)


def test_stop_operator_switches_linearly_over_its_width() -> None:
    # 2·ΔT/w with w = 2 °C: +1 per °C, clipped to ±1
    h = stop_operator(np.array([0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.5]), 2.0)
    assert h == pytest.approx([0.0, 1.0, 1.0, 1.0, 0.0, -1.0, -1.0])


def test_shapes_at_their_landmarks() -> None:
    t = np.array([0.0, 500.0])
    die = np.array([30.0, 40.0])
    step = shape_bias("bias_step", {"amplitude_dps": 0.04, "at_c": 30.0, "width_c": 1.5},
                      t, die)
    assert step[0] == pytest.approx(0.02)  # half the step at T0
    assert step[1] == pytest.approx(0.04 * 0.5 * (1 + math.tanh(10 / 1.5)))
    logistic = shape_bias("logistic_warmup",
                          {"amplitude_dps": 0.08, "t_half_s": 500.0, "width_s": 100.0}, t, die)
    assert logistic[1] == pytest.approx(0.04)
    two = shape_bias("two_exp_warmup", {"amplitude_1_dps": 0.05, "tau_1_s": 100.0,
                                        "amplitude_2_dps": 0.03, "tau_2_s": 700.0}, t, die)
    assert two == pytest.approx([0.08, 0.05 * math.exp(-5) + 0.03 * math.exp(-500 / 700)])


def test_variants_add_the_shape_to_the_truth_and_the_rate() -> None:
    cfg = SynthConfig(duration_s=1200.0, rate_hz=10.0)
    plain, _ = variant_runs(cfg, n_runs=1, seed=4)
    shaped, truth = variant_runs(cfg, shapes={"bias_step": {}}, n_runs=1, seed=4)
    added = shape_bias("bias_step", truth.shapes["bias_step"], plain[0].time_s,
                       plain[0].extra["true_temperature_c"])
    assert shaped[0].true_bias_dps["x"] - plain[0].true_bias_dps["x"] == pytest.approx(added)
    # rate re-quantised to the generator's LSB: within half an LSB of the sum
    diff = shaped[0].rates_dps["x"] - plain[0].rates_dps["x"] - added
    assert np.max(np.abs(diff)) <= 0.5 * cfg.rate_lsb_dps + 1e-12


def _ramp_run(rate_c_per_s: float) -> Prepared:
    t = np.arange(600.0)
    temp = 20.0 + rate_c_per_s * t
    return Prepared(name="ramp", time_s=t, temperature_c=temp,
                    rate_c_per_s=np.full(600, rate_c_per_s), delta_t_c=np.zeros(600),
                    chamber_c=None, rate_dps=np.zeros(600), counts=np.ones(600),
                    direction=np.ones(600))


def test_lag_limit_is_the_largest_of_hold_lsb_crossing_and_smoother() -> None:
    readout = Readout(period_s=1.3, lsb_c=1.0, noise_c=0.02, sample_rate_hz=10.0,
                      rate_lsb_dps=0.001, sample_noise_dps=0.01)
    limit = lag_limit([readout], [_ramp_run(0.02)])
    assert (limit.hold_s, limit.lsb_crossing_s, limit.smoother_s) == pytest.approx(
        (1.3, 50.0, 15.5))  # 1 °C at 0.02 °C/s: 50 s; 31-s smoother: 15.5 s
    assert limit.tau_min_s == pytest.approx(50.0)
    assert "LSB" in limit.reason()
    fine = lag_limit([Readout(1.28, 0.125, 0.02, 10.0, 0.001, 0.01)], [_ramp_run(0.05)])
    assert fine.tau_min_s == pytest.approx(15.5)  # 0.125/0.05 = 2.5 s < smoother


@pytest.fixture(scope="module")
def coarse_lag() -> tuple[list[Run], float]:
    runs, truth = variant_runs(
        SynthConfig(duration_s=6000.0, readout_lsb_c=1.0, readout_period_s=1.3,
                    effects={"thermal_lag": {}}), n_runs=4, seed=5)
    return runs, truth.base.die_tau_s


def test_a_lag_above_the_limit_is_found_through_a_coarse_readout(
    coarse_lag: tuple[list[Run], float],
) -> None:
    runs, tau = coarse_lag
    d = diagnose(runs, simulate=False)
    found = {f.effect: f.params for f in d.findings}
    assert set(found) == {"thermal_lag"}
    assert found["thermal_lag"]["tau_s"] == pytest.approx(tau, rel=0.3)
    assert not any("thermal_lag not reported" in n for n in d.notes)


def test_a_lag_below_the_limit_is_dropped_with_the_reason(
    coarse_lag: tuple[list[Run], float],
) -> None:
    runs, _ = coarse_lag
    d = diagnose(runs, simulate=False)
    final = d.selection.final
    assert "thermal_lag" in final.effects
    selector = Selector(list(d.prepared), Scaling.from_data(
        np.concatenate([p.temperature_c for p in d.prepared]),
        np.concatenate([p.delta_t_c for p in d.prepared])))
    # a readout whose LSB takes longer to cross than the fitted lag (hand-set limit)
    slow = LagLimit(hold_s=1.3, lsb_crossing_s=2.0 * final.effects["thermal_lag"],
                    smoother_s=15.5)
    kept, verdict = drop_unresolved_lag(selector, final, slow, [])
    assert "thermal_lag" not in kept.effects
    assert verdict is not None and verdict.effect == "thermal_lag"
    assert "below what the temperature readout can resolve" in verdict.reason
    assert verdict.to_dict()["verdict"] == "not resolvable at this readout"


def test_the_lag_a_coarse_readout_alone_produces_is_not_named() -> None:
    """Nothing injected (the die lags its case by 2–8 s only), 1 °C / 1.3 s readout:
    a lag passes the selection, but replays without a lag buy as much."""
    runs, truth = variant_runs(COARSE, n_runs=3, seed=1)
    assert truth.base.die_tau_s < 10.0
    d = diagnose(runs, simulate=False)
    assert "thermal_lag" not in {f.effect for f in d.findings}
    assert any("thermal_lag not reported as a physical finding" in n for n in d.notes)


@pytest.mark.parametrize(("case", "condition"), [
    ("bias_step", 0),
    ("wide_hysteresis", 1),
    ("none", 3),
])
def test_sweep_slice_scores_against_the_injected_truth(
    sweep: ModuleType, case: str, condition: int
) -> None:
    c = next(x for x in sweep.CASES if x.name == case)
    row = sweep.run_case(c, sweep.CONDITIONS[condition], seed=1)
    assert row["found"] == sorted(c.expected)
    assert row["missed"] == []
    assert row["false_alarms"] == []
