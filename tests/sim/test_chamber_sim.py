"""Simulator physics against the paper's figures and closed-form results."""

from __future__ import annotations

import numpy as np
import pytest

from gyrotherm import ConfigError
from gyrotherm.sim import (
    ChamberModel,
    ChamberProfile,
    GyroParams,
    chamber_runs,
    heating_profile,
    simulate,
)


def test_ramp_residuals_and_stability_match_fig6() -> None:
    # Fig. 6: residual std about the linear fit of the rising segment 0.57–0.84 °C;
    # chamber stability ±0.2 °C.
    for minutes in (30, 60):
        run = chamber_runs([minutes], seed=5, rate_hz=1.0)[0]
        assert run.chamber_c is not None
        t, c = run.time_s, run.chamber_c
        ramp = (t > 3600 + 120) & (t < 3600 + minutes * 60 - 120)
        coef = np.polyfit(t[ramp], c[ramp], 1)
        slope_c_per_min = coef[0] * 60
        assert slope_c_per_min == pytest.approx(70 / minutes, rel=0.15)
        resid = c[ramp] - np.polyval(coef, t[ramp])
        assert 0.4 < resid.std() < 0.9
        hold = (t > 600) & (t < 3500)
        assert 0.05 < c[hold].std() < 0.2


def test_die_follows_a_step_with_the_thermal_time_constant() -> None:
    # A set-point step from 0 to 10 °C with no chamber lag, bow or noise: the die
    # temperature is 10·(1 − e^(−t/τ)) exactly (first-order coupling).
    profile = ChamberProfile.from_pairs([(0.0, 0.0), (0.001, 10.0), (1000.0, 10.0)])
    gyro = GyroParams(tau_s=100.0).quiet()
    run = simulate(profile, name="step", gyro=gyro, rate_hz=10.0,
                   chamber=ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0))
    t = run.time_s
    die = run.extra["true_temperature_c"]
    expected = 10 * (1 - np.exp(-(t - 0.1) / 100.0))
    np.testing.assert_allclose(die[t >= 0.1], expected[t >= 0.1], atol=0.06)
    # ΔT = T_air − T_die = τ·dT/dt
    grad = run.extra["true_delta_t_c"]
    np.testing.assert_allclose(grad[1:], 100.0 * np.gradient(die, t)[1:], atol=0.1)


def test_angle_random_walk_sets_the_white_noise_level() -> None:
    # IEEE 952: per-sample std of the ARW term is N/60·√f_s (°/s) with N in °/√h.
    gyro = GyroParams(bias_instability_deg_per_h=0.0, rrw_deg_per_h_per_rth=0.0,
                      switch_on_std_dps=0.0, rate_lsb_dps=0.0, arw_deg_per_rth=0.6)
    flat = ChamberProfile.from_pairs([(0.0, 20.0), (2000.0, 20.0)])
    run = simulate(flat, name="flat", gyro=gyro, rate_hz=50.0,
                   chamber=ChamberModel(noise_c=0.0))
    resid = run.rates_dps["x"] - run.true_bias_dps["x"]
    assert resid.std() == pytest.approx(0.6 / 60 * np.sqrt(50.0), rel=0.02)


def test_sensor_quantisation_and_update_period() -> None:
    gyro = GyroParams(temperature_lsb_c=0.125, temperature_period_s=1.28)
    run = chamber_runs([10], seed=0, rate_hz=10.0, gyro=gyro, hold_s=300)[0]
    reading = run.temperature_c
    assert np.allclose(reading / 0.125, np.round(reading / 0.125))
    changes = run.time_s[1:][np.diff(reading) != 0]
    assert np.all(np.diff(changes) >= 1.28 - 0.1 - 1e-9)


def test_runs_are_reproducible_and_seeds_differ() -> None:
    a = chamber_runs([5], seed=3, rate_hz=1.0, hold_s=300)[0]
    b = chamber_runs([5], seed=3, rate_hz=1.0, hold_s=300)[0]
    c = chamber_runs([5], seed=4, rate_hz=1.0, hold_s=300)[0]
    np.testing.assert_array_equal(a.rates_dps["x"], b.rates_dps["x"])
    assert not np.array_equal(a.rates_dps["x"], c.rates_dps["x"])
    # the paper's protocol: 1 h hold, ramp, 1 h hold
    full = heating_profile(20)
    assert full.duration_s == 3600 + 20 * 60 + 3600
    assert full.setpoint_c(np.array([0.0, 3600.0, 3600 + 600.0, 9000.0])).tolist() == [
        -20.0, -20.0, 15.0, 50.0]


def test_cooling_and_cycles_work_as_set_points() -> None:
    cycle = ChamberProfile.from_pairs([(0, 20), (600, 20), (1200, -10), (1800, -10),
                                       (2400, 40), (3000, 40)])
    run = simulate(cycle, name="cycle", rate_hz=1.0, seed=1)
    grad = run.extra["true_delta_t_c"]
    t = run.time_s
    assert grad[(t > 700) & (t < 1200)].mean() < -3  # cooling: environment below die
    assert grad[(t > 1900) & (t < 2400)].mean() > 3


@pytest.mark.parametrize(
    ("pairs", "message"),
    [
        ([(0, 20)], "at least two set-points"),
        ([(5, 20), (10, 20)], "first set-point at 5.0 s"),
        ([(0, 20), (10, 20), (10, 30)], "set-point times must increase"),
        ([(0, 20), (10, 500)], "outside"),
    ],
)
def test_bad_profiles(pairs: list[tuple[float, float]], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        ChamberProfile.from_pairs(pairs)


def test_bad_gyro_params() -> None:
    with pytest.raises(ConfigError, match=r"gyro.tau_s must be > 0"):
        GyroParams(tau_s=0.0)
    with pytest.raises(ConfigError, match=r"rate_hz = 0.0 is outside"):
        simulate(heating_profile(5), name="x", rate_hz=0.0)
