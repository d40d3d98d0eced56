"""Building blocks of the diagnosis, each against an independent, hand-derived truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from gyrotherm.analysis import add_bias, allan_deviation, direction_state, lowpass
from gyrotherm.analysis._effects import ExtendedModel, design, effect_params
from gyrotherm.analysis._prep import Prepared, characterise
from gyrotherm.analysis._score import Selector, integrated_time
from gyrotherm.analysis._stats import gauss_markov_fit, heating_minus_cooling
from gyrotherm.analysis.synth._synth import SynthConfig, synth_run
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling
from gyrotherm.sim import ChamberProfile, GyroParams, simulate


def test_lowpass_step_response_is_one_minus_exponential() -> None:
    x = np.r_[0.0, np.ones(600)]
    y = lowpass(x, 100.0)
    # exact discretisation of y' = (x − y)/τ with x held over each 1-s step
    k = np.arange(1, 601)
    assert np.allclose(y[1:], 1.0 - np.exp(-k / 100.0), atol=1e-12)
    assert y[0] == 0.0


def test_direction_state_is_a_play_operator_of_the_given_width() -> None:
    t = np.array([20.0, 20.5, 20.9, 21.2, 22.0, 21.5, 21.1, 20.9, 21.5, 21.85, 22.2, 22.2])
    h = direction_state(t, 1.0)
    #            20   20.5 20.9 21.2 22  21.5 21.1 20.9 21.5 21.85 22.2 22.2
    expected = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, -1.0, -1.0, -1.0, 1.0, 1.0]
    assert h.tolist() == expected
    coarse = direction_state(np.linspace(0, 10, 100), 1.0, every=10)
    assert len(coarse) == 100 and coarse[-1] == 1.0 and coarse[0] == 0.0


def test_design_columns_and_physical_parameters() -> None:
    t = np.arange(0.0, 100.0)
    temp = 20.0 + 0.1 * t
    dt = np.full_like(t, 2.0)
    sc = Scaling(t_ref_c=25.0, t_scale_c=5.0, dt_scale_c=4.0)
    names, a = design(t, temp, dt, sc, {"cubic": 0.0, "gradient_quadratic": 0.0,
                                     "drift": 0.0, "warmup": 50.0})
    assert names == ("T^2", "T", "dT", "T*dT", "warmup", "cubic", "gradient_quadratic", "drift")
    x = (temp - 25.0) / 5.0
    assert np.allclose(a[:, 0], x**2) and np.allclose(a[:, 5], x**3)
    assert np.allclose(a[:, 4], np.exp(-t / 50.0))
    assert np.allclose(a[:, 6], 0.25) and np.allclose(a[:, 7], t / 3600.0)
    # c·x³ = c/s³·(T − T_ref)³ and c·g² = c/s_g²·ΔT²
    assert effect_params("cubic", 125.0, sc, 0.0) == {"coefficient_dps_per_c3": 1.0}
    assert effect_params("gradient_quadratic", 16.0, sc, 0.0) == {"coefficient_dps_per_c2": 1.0}
    assert effect_params("warmup", 0.1, sc, 300.0) == {"amplitude_dps": 0.1, "tau_s": 300.0}


def test_hysteresis_column_has_dead_band_and_saturation_of_one_width() -> None:
    # T: 20 → 24 (rise 4 °C), then back to 20, 1 °C per sample; width 1 °C
    temp = np.array([20.0, 21, 22, 23, 24, 23, 22, 21, 20])
    sc = Scaling(t_ref_c=22.0, t_scale_c=2.0, dt_scale_c=1.0)
    names, a = design(np.arange(9.0), temp, np.zeros(9), sc, {"hysteresis": 1.0})
    assert names[-1] == "hysteresis"
    h = a[:, -1]
    # the direction flips to +1 once T has risen more than 1 °C (at 22 °C), then h
    # saturates over 1 °C of travel counted from the flip sample's step
    up = [1 - math.exp(-d) for d in (1.0, 2.0, 3.0)]
    assert np.allclose(h[:2], 0.0) and np.allclose(h[2:5], up)
    # 23 °C: inside the dead band the state stays +1 and the travel (now 4 °C) still
    # pushes h towards it; falling: −1 once T is more than 1 °C below its high (22 °C)
    h0 = 1 - math.exp(-4.0)
    assert h[5] == pytest.approx(h0)
    down = [-1 + (h0 + 1) * math.exp(-d) for d in (1.0, 2.0, 3.0)]
    assert np.allclose(h[6:], down)


def test_hysteresis_follows_the_lagged_temperature_with_thermal_lag() -> None:
    t = np.arange(0.0, 400.0)
    temp = np.where(t < 100, 20.0, np.where(t < 200, 20.0 + 0.1 * (t - 100), 30.0))
    sc = Scaling(t_ref_c=25.0, t_scale_c=5.0, dt_scale_c=1.0)
    _, a = design(t, temp, np.zeros_like(t), sc, {"thermal_lag": 50.0, "hysteresis": 0.5})
    lagged = lowpass(temp, 50.0)
    assert np.allclose(a[:, 1], (lagged - 25.0) / 5.0)  # T column: the lagged temperature
    first = int(np.argmax(a[:, -1] != 0.0))
    # the flip: when the *lagged* temperature has risen more than 0.5 °C
    assert first == int(np.argmax(lagged - 20.0 > 0.5))
    assert first > int(np.argmax(temp - 20.0 > 0.5))


def test_joint_search_finds_both_time_constants() -> None:
    # lag 300 s and warm-up 400 s together; a joint grid + Nelder–Mead recovers both
    rng = np.random.default_rng(7)
    sc = Scaling(25.0, 10.0, 5.0)
    truth = {"thermal_lag": 300.0, "warmup": 400.0}
    runs = []
    for i in range(3):
        t = np.arange(4000.0)
        temp = 25 + 10 * np.sin(t / (250 + 60 * i)) + i
        _, x = design(t, temp, np.gradient(temp) * 100, sc, truth)
        y = x @ np.array([0.02, 0.1, 0.05, 0.0, 0.08]) + 0.3 * i + rng.normal(0, 0.002, len(t))
        runs.append(_prepared(f"r{i}", t, temp, y))
    sel = Selector(runs, sc)
    ev = sel.evaluate({"thermal_lag": 20.0, "warmup": 20.0}, search=["thermal_lag", "warmup"])
    assert ev.effects["thermal_lag"] == pytest.approx(300.0, rel=0.03)
    assert ev.effects["warmup"] == pytest.approx(400.0, rel=0.03)
    assert sel.model(ev).params()["warmup"]["amplitude_dps"] == pytest.approx(0.08, rel=0.05)


def test_allan_deviation_of_white_noise_falls_as_one_over_root_tau() -> None:
    rng = np.random.default_rng(1)
    y = [rng.standard_normal(200_000) * 0.01]
    for m in (1, 10, 100):
        assert allan_deviation(y, m) == pytest.approx(0.01 / math.sqrt(m), rel=0.06)
    assert math.isnan(allan_deviation([np.zeros(10)], 100))


def test_gauss_markov_fit_recovers_sigma_and_time_constant() -> None:
    rng = np.random.default_rng(2)
    a = math.exp(-1 / 60.0)
    runs = []
    for _ in range(6):
        w = rng.standard_normal(20_000) * 0.005 * math.sqrt(1 - a * a)
        x, _ = lfilter([1.0], [1.0, -a], w, zi=[a * rng.standard_normal() * 0.005])
        runs.append(x + rng.standard_normal(len(x)) * 0.003)  # white on top
    sigma, tau = gauss_markov_fit(runs)
    assert tau == pytest.approx(60.0, rel=0.25)
    assert sigma == pytest.approx(0.005, rel=0.25)


def test_integrated_time_of_white_noise_and_ar1() -> None:
    rng = np.random.default_rng(3)
    assert integrated_time([rng.standard_normal(50_000)]) == pytest.approx(1.0, abs=0.05)
    x = lfilter([1.0], [1.0, -0.9], rng.standard_normal(200_000))
    # AR(1): τ_int = (1 + ρ)/(1 − ρ) = 19; the sum stops once ρ^k < 0.05 (→ 18.1)
    assert integrated_time([x]) == pytest.approx(18.1, rel=0.1)


def test_heating_minus_cooling_at_equal_temperature() -> None:
    t = np.tile(np.linspace(10, 30, 1000), 2)
    d = np.r_[np.ones(1000), -np.ones(1000)]
    e = 0.02 * d + 0.001 * (t - 20)  # a slope in T must not leak into the difference
    assert heating_minus_cooling(t, d, e) == pytest.approx(0.04, abs=1e-3)


def _prepared(name: str, t: np.ndarray, temp: np.ndarray, y: np.ndarray) -> Prepared:
    rate = np.gradient(temp)
    return Prepared(name=name, time_s=t, temperature_c=temp, rate_c_per_s=rate,
                    delta_t_c=100 * rate, chamber_c=None, rate_dps=y,
                    counts=np.ones_like(t), direction=direction_state(temp, 1.0))


def test_leave_one_out_matches_explicit_dummy_regression() -> None:
    rng = np.random.default_rng(4)
    runs = []
    for i in range(4):
        t = np.arange(2000.0)
        temp = 20 + 10 * np.sin(t / (300 + 50 * i)) + i
        y = 0.01 * temp + 0.3 * i + rng.standard_normal(2000) * 0.01 + 0.05 * np.exp(-t / 200)
        runs.append(_prepared(f"r{i}", t, temp, y))
    sc = Scaling(20.0, 10.0, 5.0)
    sel = Selector(runs, sc)
    ev = sel.evaluate({"warmup": 200.0})
    for r in range(4):
        train = [j for j in range(4) if j != r]
        blocks = []
        ys = []
        for k, j in enumerate(train):
            _, x = design(runs[j].time_s, runs[j].temperature_c, runs[j].delta_t_c, sc,
                          {"warmup": 200.0})
            dummies = np.zeros((len(x), len(train)))
            dummies[:, k] = 1.0
            blocks.append(np.hstack([x, dummies]))
            ys.append(runs[j].rate_dps)
        coef, *_ = np.linalg.lstsq(np.vstack(blocks), np.concatenate(ys), rcond=None)
        _, xr = design(runs[r].time_s, runs[r].temperature_c, runs[r].delta_t_c, sc,
                       {"warmup": 200.0})
        e = runs[r].rate_dps - xr @ coef[: xr.shape[1]]
        assert ev.heldout_sse[r] == pytest.approx(float(np.sum((e - e.mean()) ** 2)), rel=1e-6)
    assert ev.effects["warmup"] == 200.0
    model = sel.model(ev)
    assert model.params()["warmup"]["amplitude_dps"] == pytest.approx(0.05, rel=0.1)
    assert sorted(model.offsets_dps) == ["r0", "r1", "r2", "r3"]


def test_add_bias_extends_a_simulated_run_on_its_true_temperature() -> None:
    profile = ChamberProfile.from_pairs([(0, 20), (600, 20), (1200, 40), (1800, 40)])
    run = simulate(profile, name="s", gyro=GyroParams().quiet(), rate_hz=1.0, seed=1)
    model = ExtendedModel(scaling=Scaling(30.0, 10.0, 5.0), effects={"drift": 0.0},
                          columns=("T^2", "T", "dT", "T*dT", "drift"),
                          coefficients=(0.0, 0.0, 0.0, 0.0, 0.36), intercept_dps=0.01)
    out = add_bias(run, model, "x")
    added = out.rates_dps["x"] - run.rates_dps["x"]
    assert np.allclose(added, 0.01 + 0.36 * run.time_s / 3600.0)
    assert np.allclose(out.true_bias_dps["x"] - run.true_bias_dps["x"], added)
    assert model.name == "paper+drift"


def test_synth_readout_is_quantised_and_held() -> None:
    cfg = SynthConfig(duration_s=1200.0, rate_hz=10.0)
    run, truth = synth_run(cfg, seed=5, truth_seed=5)
    assert np.allclose(run.temperature_c / 0.125, np.round(run.temperature_c / 0.125))
    ro = characterise(run, "x")
    assert ro.lsb_c == pytest.approx(0.125)
    assert ro.period_s == pytest.approx(1.3, abs=0.05)  # 1.28 s on a 10 Hz grid
    # the refresh itself, not rounded to the grid: what the estimator's slots must use
    # (1.3-s slots skip a 1.28-s reading every 83 s and fuse others up to 1.3 s late)
    assert ro.refresh_period_s == pytest.approx(1.28, abs=0.002)
    assert ro.sample_rate_hz == pytest.approx(10.0, rel=0.01)
    # the sensor (case) leads the die: the die is a lagged copy
    assert truth.die_tau_s < 10 and 80 <= truth.case_tau_s <= 250
    assert isinstance(run, Run) and run.chamber_c is not None


def test_refresh_period_of_a_nearly_flat_reading() -> None:
    """A 1.28-s refresh whose quantised value (0.125 °C) changes only every few
    refreshes: the refresh is 1.28 s, on the 10-Hz row grid 1.3 s (the old percentile
    of the gaps said 1.2 s)."""
    from gyrotherm.codecs import Run

    rng = np.random.default_rng(1)
    t = np.arange(0.0, 3000.0, 0.1)
    slot = np.floor(t / 1.28 + 1e-9).astype(int)
    noise = rng.normal(0.0, 0.05, slot.max() + 1)
    reading = np.round((25 + 0.3 * np.sin(slot * 1.28 / 400) + noise[slot]) / 0.125) * 0.125
    run = Run(name="flat", time_s=t, temperature_c=reading,
              rates_dps={"x": rng.normal(0.0, 0.01, len(t))})
    ro = characterise(run, "x")
    assert ro.period_s == pytest.approx(1.3, abs=1e-6)
    assert ro.refresh_period_s == pytest.approx(1.28, abs=0.002)


def test_synth_effect_is_in_the_true_bias() -> None:
    cfg = SynthConfig(duration_s=1200.0, effects={"drift": {"slope_dps_per_h": 0.36}})
    with_drift, _ = synth_run(cfg, seed=6, truth_seed=6)
    without, _ = synth_run(SynthConfig(duration_s=1200.0), seed=6, truth_seed=6)
    diff = with_drift.true_bias_dps["x"] - without.true_bias_dps["x"]
    assert np.allclose(diff, 0.36 * with_drift.time_s / 3600.0, atol=1e-6)
