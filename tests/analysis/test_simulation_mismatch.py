"""The simulation comparison: statistics scored against several replays (z-scores).

Truths used here: a drift injected by the independent generator must show as a
significant mismatch in the drift statistic and vanish when the extended model
(which found the drift) is replayed; data from gyrotherm's own simulator — whose
physics the replays reproduce — must look like the replays; heat-only runs cannot
show heating-vs-cooling statistics; Student's t with 4 degrees of freedom has a
closed-form CDF.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from gyrotherm.analysis import SynthConfig, diagnose, synth_runs
from gyrotherm.analysis._stats import replay_spread, z_score, z_threshold
from gyrotherm.sim import chamber_runs

FAST = SynthConfig(duration_s=6000.0, rate_hz=10.0)
#: statistics that the candidate effects move (the rest describe the noise's shape)
EFFECT_STATISTICS = {
    "drift_dps_per_h", "first_10min_dps", "heating_minus_cooling_dps",
    "rate_sign_difference_dps", "large_gradient_excess_dps", "residual_vs_temperature_dps",
}


def _t4_cdf(t: float) -> float:
    """Student's t CDF for 4 degrees of freedom, closed form (x = t / √(t² + 4))."""
    x = t / math.sqrt(t * t + 4.0)
    return 0.5 + 0.75 * x - 0.25 * x**3


def test_z_threshold_is_the_three_sigma_prediction_bound_of_one_more_replay() -> None:
    thr = z_threshold(5)
    # |z|/√(1 + 1/5) is t-distributed with 4 dof; two-sided tail 0.0027 (Gaussian 3σ)
    assert 2.0 * (1.0 - _t4_cdf(thr / math.sqrt(1.2))) == pytest.approx(0.0027, rel=1e-6)
    assert thr == pytest.approx(7.25, abs=0.01)
    assert z_threshold(10_000) == pytest.approx(3.0, abs=0.01)  # Gaussian limit
    assert math.isnan(z_threshold(1))


def test_replay_spread_and_z_guard() -> None:
    mean, std, n = replay_spread([1.0, 2.0, math.nan, 3.0])
    assert (mean, std, n) == (2.0, 1.0, 3)  # NaN skipped, ddof 1
    assert z_score(4.0, mean, std) == 2.0
    # replays that all agree: a finite, huge |z| for a different value, 0 for the same
    assert z_score(1.0, 1.0, 0.0) == 0.0
    assert math.isfinite(z_score(1.1, 1.0, 0.0)) and z_score(1.1, 1.0, 0.0) > 1e6
    assert math.isnan(z_score(1.0, math.nan, 1.0))


@pytest.mark.parametrize("seed", [101, 207])
def test_injected_drift_is_a_significant_mismatch_that_the_extended_replay_closes(
    seed: int,
) -> None:
    runs, truth = synth_runs(replace(FAST, effects={"drift": {}}), n_runs=4, seed=seed)
    result = diagnose(runs, seed=seed)
    assert [f.effect for f in result.findings] == ["drift"]
    sim = result.simulation
    assert sim is not None and sim.replays == 5
    names = [m.statistic for m in sim.mismatch]
    assert [abs(m.z) for m in sim.mismatch] == sorted((abs(m.z) for m in sim.mismatch),
                                                       reverse=True)
    drift = sim.mismatch[names.index("drift_dps_per_h")]
    # the paper model cannot drift: its replays scatter about 0, the measurement does not
    assert drift.significant and abs(drift.z) > sim.z_threshold
    assert names.index("drift_dps_per_h") < len(names) // 2  # in the top half of the list
    # with the fitted drift in the simulator the measured value is an ordinary replay
    assert drift.extended_z is not None and abs(drift.extended_z) < sim.z_threshold
    assert drift.extended_significant is False
    data = result.to_dict()["simulation"]
    assert data["replays"] == 5 and data["z_threshold"] == pytest.approx(sim.z_threshold)
    assert "drift_dps_per_h" in data["significant"]
    entry = data["mismatch"][names.index("drift_dps_per_h")]
    for key in ("statistic", "measured", "simulated", "simulated_extended", "sim_mean",
                "sim_std", "z", "significant", "extended_mean", "extended_std",
                "extended_z", "extended_significant"):
        assert key in entry, key
    assert truth.effects["drift"]["slope_dps_per_h"] * drift.measured > 0  # same sign


@pytest.mark.parametrize("seed", [3, 104, 512])
def test_nothing_injected_marks_no_effect_statistic(seed: int) -> None:
    """Null data from the independent generator, whose noise (white, Gauss–Markov AND
    rate random walk, quantised readout) is deliberately not the simulator's (white +
    one Gauss–Markov process): on long runs the noise-shape statistics (Allan
    deviations, residual RMS, correlation time) may legitimately differ. The effect
    statistics must not: with the threshold at a 0.0027 two-sided tail per statistic,
    6 of them are all unmarked with probability ≥ 98 %, and two are marked with
    probability ≤ 15·0.0027² ≈ 10⁻⁴ — so at most one, by chance."""
    runs, _ = synth_runs(FAST, n_runs=4, seed=seed)
    result = diagnose(runs, seed=seed)
    assert result.findings == ()
    sim = result.simulation
    assert sim is not None
    marked = {m.statistic for m in sim.significant}
    assert len(marked & EFFECT_STATISTICS) <= 1, marked
    scored = {m.statistic for m in sim.mismatch}
    assert EFFECT_STATISTICS <= scored  # all defined on these runs (heat, cool, holds)
    for m in sim.mismatch:  # nothing found: the extended replay is the baseline's
        assert m.extended_z == m.z


def test_own_simulator_matches_its_replays_and_heat_only_statistics_are_noted() -> None:
    """The reviewer's case: 3 runs of gyrotherm's own simulator (Tang's heat-then-hold
    chamber runs), which the calibrated replays reproduce. A right simulator marks
    each of the K ≤ 14 statistics with probability 0.0027: none with probability
    ≥ 96 %, two or more ≤ 91·0.0027² ≈ 7·10⁻⁴ — so at most one, by chance. The runs
    only heat: the cooling-dependent statistics are undefined and must be listed,
    with the reason, in the notes rather than dropped silently."""
    runs = chamber_runs([5, 20, 40], seed=3, hold_s=1800.0)
    result = diagnose(runs, seed=3)
    assert result.findings == ()
    sim = result.simulation
    assert sim is not None
    assert len(sim.significant) <= 1, [(m.statistic, m.z) for m in sim.significant]
    omitted = dict(sim.omitted)
    assert set(omitted) == {"heating_minus_cooling_dps", "rate_sign_difference_dps"}
    assert "last move was cooling" in omitted["heating_minus_cooling_dps"]
    assert "dT/dt < −0.002 °C/s" in omitted["rate_sign_difference_dps"]
    data = result.to_dict()
    notes = "\n".join(data["notes"])
    for name in omitted:
        assert f"statistic {name} left out of the mismatch list" in notes
        assert name not in {m["statistic"] for m in data["simulation"]["mismatch"]}
    assert {o["statistic"] for o in data["simulation"]["omitted"]} == set(omitted)
    assert len(data["simulation"]["mismatch"]) + len(omitted) == 14


def test_fewer_than_two_replays_is_a_config_error() -> None:
    from gyrotherm._errors import ConfigError

    runs = chamber_runs([5, 20], seed=1, hold_s=900.0)
    assert diagnose(runs, replays=1, simulate=False).simulation is None  # no replays asked
    with pytest.raises(ConfigError, match="replays = 1 is below 2"):
        diagnose(runs, replays=1)
