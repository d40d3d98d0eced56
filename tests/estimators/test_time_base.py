"""The estimator when the frame time base steps back (clock step, restarted log)."""

from __future__ import annotations

import pytest

from gyrotherm.estimators import EstimatorConfig, TemperatureEstimator


def test_time_base_stepping_back_reinitialises_and_warms_up_again() -> None:
    # 1000 s flat, then the clock restarts at 0 during a 0.05 °C/s ramp: the filter
    # must start again and track the ramp (ΔT = τ·Ṫ = 120·0.05 = 6 °C), not freeze.
    cfg = EstimatorConfig(tau_s=120.0, noise_c=0.001, quantisation_c=0.0)
    est = TemperatureEstimator(cfg)
    for k in range(1000):
        est.update(float(k), 20.0)
    assert est.estimate().updates == 1000
    out = est.update(0.0, 20.0)
    assert est.time_resets == 1 and out.updates == 1
    for k in range(1, 600):
        out = est.update(float(k), 20.0 + 0.05 * k)
    assert out.delta_t_c == pytest.approx(6.0, rel=0.02)
    assert not out.stale
