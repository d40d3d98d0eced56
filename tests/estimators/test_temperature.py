"""The T / ΔT Kalman estimator against simulator truth and hand-made cases."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gyrotherm import ConfigError
from gyrotherm.estimators import EstimatorConfig, TemperatureEstimator, estimate_series
from gyrotherm.sim import GyroParams, chamber_runs


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a * a)))


def _finite_difference_delta_t(time_s: np.ndarray, reading: np.ndarray, period_s: float,
                               tau_s: float) -> np.ndarray:
    """ΔT = τ·dT/dt from a central difference of the raw readings, one per sensor period."""
    step = max(1, round(period_s / (time_s[1] - time_s[0])))
    idx = np.arange(0, len(time_s), step)
    fd = np.gradient(reading[idx], time_s[idx]) * tau_s
    return np.interp(time_s, time_s[idx], fd)


@pytest.mark.parametrize(
    ("lsb_c", "period_s"),
    [(0.01, 0.1), (0.125, 1.28)],  # CAN resolution; a common IMU's readout
)
def test_delta_t_beats_finite_difference_against_truth(lsb_c: float, period_s: float) -> None:
    gyro = GyroParams(temperature_lsb_c=lsb_c, temperature_period_s=period_s)
    cfg = EstimatorConfig(tau_s=gyro.tau_s, quantisation_c=lsb_c, update_period_s=period_s)
    for run in chamber_runs([5, 60], seed=4, rate_hz=5.0, gyro=gyro, hold_s=1200):
        truth = run.extra["true_delta_t_c"]
        kf = estimate_series(run.time_s, run.temperature_c, cfg).delta_t_c
        fd = _finite_difference_delta_t(run.time_s, run.temperature_c, period_s, gyro.tau_s)
        assert _rms(kf - truth) < 0.5 * _rms(fd - truth), run.name
        assert _rms(kf - truth) < 1.0  # °C, against a ΔT reaching 10–25 °C


def test_constant_ramp_is_tracked_exactly_in_steady_state() -> None:
    # T = 20 + 0.05 t, read without noise: the filter must settle on dT/dt = 0.05 °C/s.
    est = TemperatureEstimator(EstimatorConfig(tau_s=100.0, noise_c=0.001, quantisation_c=0.0))
    for k in range(2000):
        out = est.update(k * 0.5, 20 + 0.05 * k * 0.5)
    assert out.rate_c_per_s == pytest.approx(0.05, rel=1e-3)
    assert out.delta_t_c == pytest.approx(5.0, rel=1e-3)  # τ·Ṫ = 100 s · 0.05 °C/s
    assert out.temperature_c == pytest.approx(20 + 0.05 * 1999 * 0.5, abs=1e-3)
    assert out.delta_t_std_c == pytest.approx(100.0 * out.rate_std_c_per_s)
    assert not out.stale and not out.rejected


def test_spike_is_gated_and_step_reinitialises() -> None:
    cfg = EstimatorConfig(noise_c=0.02, max_consecutive_rejections=3)
    est = TemperatureEstimator(cfg)
    for k in range(200):
        est.update(k * 0.1, 25.0)
    spike = est.update(20.0, 40.0)
    assert spike.rejected and spike.temperature_c == pytest.approx(25.0, abs=0.01)
    after = est.update(20.1, 25.0)
    assert not after.rejected
    # a real step persists: after max_consecutive_rejections readings the filter follows it
    outs = [est.update(20.2 + 0.1 * k, 35.0) for k in range(3)]
    assert outs[-1].temperature_c == pytest.approx(35.0, abs=0.05)
    assert est.rejected_total == 4 and est.reinitialisations == 1


def test_predict_only_and_stale_flag() -> None:
    est = TemperatureEstimator(EstimatorConfig(stale_after_s=2.0, noise_c=0.001))
    assert est.estimate().stale and math.isnan(est.estimate().temperature_c)
    for k in range(100):
        est.update(k * 0.1, 10 + 0.1 * k * 0.1)  # 0.1 °C/s
    fresh = est.estimate(10.0)
    assert not fresh.stale
    later = est.predict(11.5)  # 1.6 s without readings: extrapolated, not yet stale
    assert later.temperature_c == pytest.approx(10 + 0.1 * 11.5, abs=0.02)
    assert not later.stale
    assert est.predict(13.0).stale
    assert est.predict(13.0).temperature_std_c > fresh.temperature_std_c


def test_non_finite_reading_is_rejected_not_fused() -> None:
    est = TemperatureEstimator()
    est.update(0.0, 20.0)
    out = est.update(0.1, float("nan"))
    assert out.rejected and out.temperature_c == pytest.approx(20.0)


def test_estimate_is_frozen() -> None:
    out = TemperatureEstimator().update(0.0, 20.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.temperature_c = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("tau_s", 0.0, r"estimator.tau_s = 0.0 is outside"),
        ("gate_sigma", 0.5, r"estimator.gate_sigma = 0.5 is outside"),
        ("stale_after_s", float("nan"), r"estimator.stale_after_s = nan"),
        ("noise_c", "hot", r"estimator.noise_c: expected a number"),
    ],
)
def test_config_errors_name_the_field(field: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        EstimatorConfig(**{field: value})  # type: ignore[arg-type]


def test_config_from_dict_rejects_unknown_fields() -> None:
    with pytest.raises(ConfigError, match=r"unknown field\(s\) \['tau'\]"):
        EstimatorConfig.from_dict({"tau": 3.0})
    assert EstimatorConfig.from_dict(EstimatorConfig().to_dict()) == EstimatorConfig()
