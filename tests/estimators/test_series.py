"""estimate_series (float arithmetic, flight-log scale) against the filterpy estimator.

The reference is :class:`TemperatureEstimator` on its filterpy engine fed row by row
with the same slot rule; both must agree to 1e-9 on every row, through gating, spike
rejection, re-initialisation after repeated rejections, time steps back and
forward, non-finite readings, held (repeated) readings and F/Q reuse.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm.estimators import EstimatorConfig, TemperatureEstimator, _series, estimate_series


def reference(time_s: np.ndarray, temperature_c: np.ndarray,
              cfg: EstimatorConfig) -> tuple[np.ndarray, np.ndarray]:
    est = TemperatureEstimator(cfg, engine="filterpy")
    n = len(time_s)
    if cfg.update_period_s > 0:
        slot = np.floor(time_s / cfg.update_period_s + 1e-9)
        fed = np.r_[True, slot[1:] != slot[:-1]]
    else:
        fed = np.ones(n, dtype=bool)
    t_out, r_out = np.empty(n), np.empty(n)
    temp = rate = math.nan
    for i in range(n):
        if fed[i]:
            est.update(float(time_s[i]), float(temperature_c[i]))
            temp, rate = est._state()
        t_out[i], r_out[i] = temp, rate
    return t_out, cfg.tau_s * r_out


def hostile_series(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A heating ramp read by a quantised, held sensor, with spikes, a real step,
    a time step back, a gap, and non-finite readings."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    true = 20 + 0.01 * t + 0.5 * np.sin(t / 7)
    held = np.floor(t / 0.04)
    fresh = np.r_[True, held[1:] != held[:-1]]
    reading = np.round((true + rng.normal(0, 0.02, n)) / 0.0625) * 0.0625
    reading = reading[fresh][np.cumsum(fresh) - 1]  # held between refreshes
    spikes = rng.choice(n, n // 200, replace=False)
    reading[spikes] += rng.choice([-1, 1], len(spikes)) * 30
    reading[n // 2:] += 8.0                   # a real step: re-initialisation
    t[2 * n // 3:] -= 20.0                    # time base steps back
    t[5 * n // 6:] += 3000.0                  # a gap forward
    reading[rng.choice(n, 5, replace=False)] = np.nan
    return t, reading


@pytest.mark.parametrize("period_s", [0.0, 0.04, 1.0])
def test_matches_filterpy_estimator_row_by_row(period_s: float) -> None:
    t, z = hostile_series(3, 6000)
    cfg = EstimatorConfig(update_period_s=period_s, quantisation_c=0.0625)
    want_t, want_d = reference(t, z, cfg)
    got = estimate_series(t, z, cfg)
    np.testing.assert_allclose(got.temperature_c, want_t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.delta_t_c, want_d, rtol=0, atol=1e-9)
    assert np.isfinite(got.temperature_c).all()


def test_blocks_do_not_change_the_result(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rows are converted a block at a time: block edges (also inside a slot of the
    update period) give the same series."""
    t, z = hostile_series(4, 3000)
    cfg = EstimatorConfig(update_period_s=0.04)
    whole = estimate_series(t, z, cfg)
    monkeypatch.setattr(_series, "_BLOCK_ROWS", 7)
    blocked = estimate_series(t, z, cfg)
    np.testing.assert_array_equal(blocked.temperature_c, whole.temperature_c)
    np.testing.assert_array_equal(blocked.delta_t_c, whole.delta_t_c)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-200, 200)), min_size=1, max_size=60),
       st.sampled_from([0.0, 0.5]))
def test_matches_on_arbitrary_series(rows: list[tuple[float, float]], period_s: float) -> None:
    """Any finite time stamps (not sorted) and readings: the same rows."""
    t = np.array([r[0] for r in rows])
    z = np.array([r[1] for r in rows])
    cfg = EstimatorConfig(update_period_s=period_s)
    want_t, want_d = reference(t, z, cfg)
    got = estimate_series(t, z, cfg)
    np.testing.assert_allclose(got.temperature_c, want_t, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got.delta_t_c, want_d, rtol=1e-12, atol=1e-9)


def test_online_slot_rule_equals_the_offline_one() -> None:
    """A 1.28-s reading repeated in 10 Hz frames, update_period_s = 1.28: the online
    estimator fuses one reading per slot as estimate_series does (equal T and ΔT on
    every row), a repeat of an accepted reading keeps the estimate fresh although the
    period exceeds stale_after_s, and a repeat of a rejected one does not."""
    cfg = EstimatorConfig(update_period_s=1.28, stale_after_s=1.0)
    t = np.arange(0.0, 300.0, 0.1)
    slot = np.floor(t / 1.28 + 1e-9)
    reading = np.round((20.0 + 0.05 * slot * 1.28) / 0.125) * 0.125  # held, quantised
    offline = estimate_series(t, reading, cfg)
    est = TemperatureEstimator(cfg)
    online = [est.update(float(a), float(b)) for a, b in zip(t, reading, strict=True)]
    np.testing.assert_allclose([e.temperature_c for e in online], offline.temperature_c,
                               atol=1e-9)
    np.testing.assert_allclose([e.delta_t_c for e in online], offline.delta_t_c, atol=1e-9)
    assert online[-1].updates == len(np.unique(slot))
    assert not any(e.stale for e in online)  # 1.28 s > stale_after_s, repeats arrive
    spike = TemperatureEstimator(cfg)
    for a, b in zip(t[:100], reading[:100], strict=True):
        spike.update(float(a), float(b))
    first = math.floor(10.0 / 1.28 + 1e-9) + 1  # the next slot opens with a spike
    t0 = first * 1.28
    assert spike.update(t0, 500.0).rejected
    assert spike.update(t0 + 1.2, 500.0).stale  # its repeats do not count as fresh
