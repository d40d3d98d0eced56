"""A structure in time beside a hysteresis that is the hysteresis' own timing
(:mod:`gyrotherm.analysis._rate_width`, round 14 of issue 19): the warped temperature by
hand, the catalogue's form as its limit, and the diagnosis on development seeds of
shapes-dev3 (sweep seeds 573 and 576 at 200 Hz: round 13 named a structure in time beside
the hysteresis, a false alarm)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._effects import direction_state, hysteresis_state
from gyrotherm.analysis._rate_width import rate_width_state, warped_temperature
from gyrotherm.analysis.synth._variants import variant_runs

FAST = SynthConfig(duration_s=6000.0, rate_hz=200.0, readout_lsb_c=0.0625,
                   readout_period_s=0.1)
"""The sweep's 200 Hz, 0.0625 °C / 0.1 s condition (4 runs)."""


def test_warped_temperature_by_hand() -> None:
    t = np.arange(0.0, 101.0)
    ramp = 20.0 + 0.05 * t  # 0.05 °C/s
    # a constant rate r: every step is divided by 1 + r/r₀
    warped = warped_temperature(t, ramp, 0.025)
    np.testing.assert_allclose(warped, 20.0 + 0.05 * t / 3.0, atol=1e-12)
    # r₀ far above the rate: the temperature itself
    np.testing.assert_allclose(warped_temperature(t, ramp, 1e9), ramp, atol=1e-6)
    # a hold stays a hold, and the direction of every step is kept
    zigzag = np.r_[np.linspace(20, 30, 51), np.linspace(30, 25, 50)]
    w = warped_temperature(np.arange(101.0), zigzag, 0.01)
    assert np.all(np.sign(np.diff(w)) == np.sign(np.diff(zigzag)))


def test_a_rate_far_above_the_ramps_is_the_catalogues_hysteresis() -> None:
    t = np.arange(0.0, 400.0)
    temp = 25.0 + 5.0 * np.sin(2 * np.pi * t / 200.0)
    width = 0.8
    catalogued = hysteresis_state(temp, direction_state(temp, width), width)
    np.testing.assert_allclose(rate_width_state(t, temp, width, 1e9), catalogued, atol=1e-6)
    # a width that grows with the rate: the state saturates later on the same ramp
    slow = rate_width_state(t, temp, width, 0.02)
    assert np.mean(np.abs(slow)) < np.mean(np.abs(catalogued))


def test_the_structure_in_time_beside_a_rate_dependent_hysteresis_is_its_timing() -> None:
    for seed in (573, 576):  # round 13: hysteresis + unexplained in time (×1.14, ×1.15)
        runs, truth = variant_runs(FAST, shapes={"rate_hysteresis": {}}, n_runs=4,
                                   seed=seed)
        d = diagnose(runs, simulate=False)
        assert [f.effect for f in d.findings] == ["hysteresis"], seed
        assert d.unexplained == (), seed
        (f,) = d.findings
        assert "widens with the rate" in f.shape, f.shape
        true = truth.shapes["rate_hysteresis"]["amplitude_dps"]
        assert np.sign(f.params["amplitude_dps"]) == np.sign(true)
        assert any("not reported: a hysteresis whose width grows" in n for n in d.notes)


def test_a_genuine_structure_in_time_beside_a_hysteresis_is_kept() -> None:
    # a logistic warm-up beside the generator's hysteresis: the rate-dependent width
    # cannot stand in for a decay centred at t½, so a structure in time (or the warm-up)
    # is still named
    cfg = replace(FAST, effects={"hysteresis": {}})
    runs, _ = variant_runs(cfg, shapes={"logistic_warmup": {}}, n_runs=4, seed=574)
    d = diagnose(runs, simulate=False)
    named = {f.effect for f in d.findings} | {f"unexplained:{u.variable}"
                                              for u in d.unexplained}
    assert "hysteresis" in named
    assert named & {"warmup", "unexplained:time_since_power_on_s"}, named
