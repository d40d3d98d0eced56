"""Hidden-effect tests: runs from an independent generator, effects injected with
random parameters; the diagnosis is not told which and must name them, estimate
their parameters within 30 % and report a held-out gain above 1.1 — and report
nothing when nothing was injected (two-node thermal physics, 0.125 °C / 1.28 s
readout, Gauss–Markov noise, switch-on offsets all present)."""

from __future__ import annotations

import pytest

from gyrotherm.analysis import SCHEMA, SynthConfig, diagnose, synth_runs
from gyrotherm.analysis.synth._synth import SynthTruth
from gyrotherm.sim import chamber_runs

#: parameters whose estimates must fall within 30 % of the truth
CHECKED = {
    "thermal_lag": ("tau_s",),
    "hysteresis": ("amplitude_dps",),
    "warmup": ("amplitude_dps", "tau_s"),
    "cubic": ("coefficient_dps_per_c3",),
    "gradient_quadratic": ("coefficient_dps_per_c2",),
    "drift": ("slope_dps_per_h",),
}
FAST = SynthConfig(duration_s=6000.0, rate_hz=10.0)


def _check_found(truth: SynthTruth, result_effects: dict[str, dict[str, float]]) -> None:
    assert set(result_effects) == set(truth.effects), (truth.effects, result_effects)
    for name, params in truth.effects.items():
        for key in CHECKED[name]:
            assert result_effects[name][key] == pytest.approx(params[key], rel=0.3), (name, key)


def _run(effects: dict[str, dict[str, float]], seed: int, cfg: SynthConfig = FAST,
         n_runs: int = 4) -> None:
    from dataclasses import replace

    runs, truth = synth_runs(replace(cfg, effects=effects), n_runs=n_runs, seed=seed)
    result = diagnose(runs, simulate=False)
    _check_found(truth, {f.effect: dict(f.params) for f in result.findings})
    data = result.to_dict()
    assert data["schema"] == SCHEMA
    if effects:
        assert result.gain > 1.1
        assert data["extended"]["gain"] > 1.1
        if len(effects) == 1:  # alone == extended
            assert data["findings"][0]["gain"] == pytest.approx(data["extended"]["gain"])
        assert sorted(data["extended"]["effects"]) == sorted(effects)
    else:
        assert data["findings"] == []
        assert data["extended"]["effects"] == [] and data["extended"]["gain"] == 1.0


@pytest.mark.parametrize("effect", sorted(CHECKED))
@pytest.mark.parametrize("seed", [101, 207])
def test_finds_one_hidden_effect(effect: str, seed: int) -> None:
    _run({effect: {}}, seed)


@pytest.mark.parametrize("seed", [3, 104, 512])
def test_reports_nothing_when_nothing_is_injected(seed: int) -> None:
    _run({}, seed)


@pytest.mark.parametrize(("pair", "seed"), [
    (("gradient_quadratic", "hysteresis"), 28),
    (("thermal_lag", "drift"), 23),
    (("cubic", "gradient_quadratic"), 26),
])
def test_finds_two_hidden_effects(pair: tuple[str, str], seed: int) -> None:
    _run({pair[0]: {}, pair[1]: {}}, seed)


#: Every pair with a hysteresis, in the order (and so with the parameter draws) of the
#: first sweep that measured them, and seeds fixed before any result was seen: these
#: seeds were not chosen, and must not be changed, to make the tests pass.
HYSTERESIS_PAIRS = [
    ("hysteresis", "thermal_lag"),
    ("hysteresis", "warmup"),
    ("cubic", "hysteresis"),
    ("gradient_quadratic", "hysteresis"),
    ("drift", "hysteresis"),
]
PAIR_SEEDS = (101, 102, 103)


@pytest.mark.slow
@pytest.mark.parametrize("seed", PAIR_SEEDS)
@pytest.mark.parametrize("pair", HYSTERESIS_PAIRS, ids="+".join)
def test_finds_hysteresis_with_any_second_effect(pair: tuple[str, str], seed: int) -> None:
    _run({pair[0]: {}, pair[1]: {}}, seed)


@pytest.mark.slow
def test_short_runs_at_one_kilohertz() -> None:
    cfg = SynthConfig(duration_s=1200.0, rate_hz=1000.0)
    _run({"warmup": {"tau_s": 180.0}}, 41, cfg=cfg)


def test_gyrotherm_simulator_runs_show_nothing_and_simulation_matches() -> None:
    """A second generator: gyrotherm's own simulator, whose truth is the paper model."""
    runs = chamber_runs([5, 20, 40, 60], seed=3, hold_s=1800.0)
    result = diagnose(runs)
    assert result.findings == ()
    sim = result.simulation
    assert sim is not None
    stats = {m.statistic: m for m in sim.mismatch}
    # calibrated white noise and offsets reproduce the measured ones
    assert stats["arw_deg_per_rth"].simulated == pytest.approx(
        stats["arw_deg_per_rth"].measured, rel=0.1)
    assert sim.calibration.gyro.tau_s == pytest.approx(120.0, rel=0.05)
    # its replays reproduce it: at most one statistic marked, by chance (each 0.0027)
    assert len(sim.significant) <= 1
