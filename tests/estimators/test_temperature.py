"""The T / ΔT Kalman estimator against simulator truth and hand-made cases."""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
import pytest

from gyrotherm import ConfigError
from gyrotherm.estimators import EstimatorConfig, TemperatureEstimator, estimate_series
from gyrotherm.sim import GyroParams, chamber_runs


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a * a)))


#: Finite-difference windows W, in sensor periods P.
FD_WINDOWS_P = (1, 2, 5, 10, 30, 60)
FINE, COARSE = (0.01, 0.1), (0.125, 1.28)  # (LSB °C, period s): CAN resolution; a common IMU
SEED = 4


def _raw_readings(time_s: np.ndarray, reading: np.ndarray,
                  period_s: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The sensor's own samples: the first row of each slot floor(t/P) (the simulator's refresh)."""
    slot = np.floor(time_s / period_s + 1e-9)
    first = np.r_[True, slot[1:] != slot[:-1]]
    return time_s[first], reading[first]


def _difference_delta_t(time_s: np.ndarray, sample_t: np.ndarray, sample_c: np.ndarray,
                        window_s: float, tau_s: float, *, centred: bool) -> np.ndarray:  # fmt: skip
    """ΔT = τ·(T(t+W/2) − T(t−W/2))/W at every row (T linear between raw readings);
    ``centred=False``: the causal backward difference τ·(T(t) − T(t−W))/W."""
    after, before = (time_s + window_s / 2, time_s - window_s / 2) if centred else (
        time_s, time_s - window_s)  # fmt: skip
    return tau_s * (np.interp(after, sample_t, sample_c) - np.interp(before, sample_t, sample_c)) \
        / window_s  # fmt: skip


class Comparison(NamedTuple):
    """ΔT RMS errors against simulator truth (°C) of one run."""

    run: str
    kalman_c: float
    centred_c: float  # best centred difference, window chosen by its error against truth
    centred_window_p: int
    backward_c: float  # best causal (backward) difference, chosen the same way
    backward_window_p: int


def compare(sensor: tuple[float, float], seed: int = SEED) -> list[Comparison]:
    """The Kalman ΔT against oracle-tuned finite differences on the 5- and 60-min runs."""
    lsb_c, period_s = sensor
    gyro = GyroParams(temperature_lsb_c=lsb_c, temperature_period_s=period_s)
    cfg = EstimatorConfig(tau_s=gyro.tau_s, quantisation_c=lsb_c, update_period_s=period_s)
    out = []
    for run in chamber_runs([5, 60], seed=seed, rate_hz=5.0, gyro=gyro, hold_s=1200):
        truth = run.extra["true_delta_t_c"]
        kf = _rms(estimate_series(run.time_s, run.temperature_c, cfg).delta_t_c - truth)
        st, sc = _raw_readings(run.time_s, run.temperature_c, period_s)
        best = {}
        for centred in (True, False):
            errors = {m: _rms(_difference_delta_t(run.time_s, st, sc, m * period_s, gyro.tau_s,
                                                  centred=centred) - truth)
                      for m in FD_WINDOWS_P}  # fmt: skip
            m_best = min(errors, key=errors.__getitem__)
            best[centred] = (errors[m_best], m_best)
        out.append(Comparison(run.name, kf, *best[True], *best[False]))
    return out


def test_difference_baseline_is_exact_on_a_ramp() -> None:
    t = np.arange(0, 100, 0.2)
    ramp = 20 + 0.05 * t  # Ṫ = 0.05 °C/s, τ = 120 s: ΔT = 6 °C
    st, sc = _raw_readings(t, ramp, 1.28)
    assert np.allclose(np.diff(st)[:3], [1.4, 1.2, 1.4])  # slots of 1.28 s on a 0.2 s grid
    for centred in (True, False):
        fd = _difference_delta_t(t, st, sc, 12.8, 120.0, centred=centred)
        assert np.allclose(fd[100:400], 6.0)  # away from the ends


def test_delta_t_beats_oracle_tuned_finite_difference_on_a_fine_sensor() -> None:
    """0.01 °C / 0.1 s: the filter beats the best centred difference (W ≤ 60 P) of each run.

    Measured (seed 4): 5-min run 0.326 vs 0.572 °C (0.57×), 60-min run 0.102 vs
    0.571 °C (0.18×); seeds 4–7: 0.56–0.57× and 0.16–0.19×. The best window is the
    largest allowed (6 s); longer ones win (docs/model.md: 0.111 °C at 48 s).
    """
    for c in compare(FINE):
        assert c.kalman_c < 0.65 * c.centred_c, c
        assert c.kalman_c < 0.65 * c.backward_c, c


def test_delta_t_on_a_coarse_sensor_loses_to_the_centred_difference() -> None:
    """0.125 °C / 1.28 s: a known limitation, pinned so that docs/model.md stays true.

    The oracle-tuned centred difference (non-causal: it sees W/2 ahead; the filter
    is causal, as the daemon must be) wins: measured (seed 4) 5-min run 0.748 vs
    0.137 °C (5.4×, W = 30 P), 60-min run 0.119 vs 0.098 °C (1.2×, W = 60 P).
    Against the best causal (backward) difference (W ≤ 60 P) the filter wins on the
    60-min run (0.79×) and loses on the 5-min run (1.69×): its lag at the ramp's corners.
    """
    short, long = compare(COARSE)
    for c in (short, long):
        assert c.centred_c < c.kalman_c < 1.0, c  # °C, against a ΔT reaching 2.8–24 °C
    assert short.kalman_c < 6.5 * short.centred_c
    assert long.kalman_c < 1.4 * long.centred_c
    assert long.kalman_c < 0.9 * long.backward_c


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


def _textbook_filter(time_s: list[float], reading_c: list[float],
                     cfg: EstimatorConfig) -> list[tuple[float, float]]:  # fmt: skip
    """[T, dT/dt] after each reading, from the textbook equations with F and Q built
    from every step's own dt (no filterpy, no caching, no gating)."""
    r, q = cfg.measurement_variance_c2, cfg.process_noise_c2_per_s3
    x = np.array([reading_c[0], 0.0])
    p = np.diag([r, cfg.initial_rate_std_c_per_s**2])
    out = [(float(x[0]), float(x[1]))]
    for k in range(1, len(time_s)):
        dt = time_s[k] - time_s[k - 1]
        f = np.array([[1.0, dt], [0.0, 1.0]])
        x = f @ x
        p = f @ p @ f.T + q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        gain = p[:, 0] / (p[0, 0] + r)
        x = x + gain * (reading_c[k] - x[0])
        p = p - np.outer(gain, p[0, :])
        out.append((float(x[0]), float(x[1])))
    return out


def test_matches_textbook_filter_with_jittered_and_changing_steps() -> None:
    """Time stamps i·0.1 s differ from step to step in their last bits (the filter
    reuses F and Q for those), and real gaps change dt (it must rebuild them)."""
    rng = np.random.default_rng(11)
    steps = [0.1] * 300 + [0.35] * 20 + [0.1] * 100 + [1.28] * 30 + [0.1] * 50
    time_s = np.concatenate([[0.0], np.cumsum(steps)])
    time_s[1:301] = np.arange(1, 301) * 0.1  # i * 0.1: ULP-level jitter in dt
    reading_c = 25.0 + 0.004 * time_s + rng.normal(0.0, 0.02, time_s.size)
    assert len(set(np.diff(time_s[:301]).tolist())) > 1  # the jitter is really there
    cfg = EstimatorConfig(gate_sigma=1000.0)  # no gating on this data
    est = TemperatureEstimator(cfg)
    got = [est.update(t, c) for t, c in zip(time_s.tolist(), reading_c.tolist(), strict=True)]
    want = _textbook_filter(time_s.tolist(), reading_c.tolist(), cfg)
    np.testing.assert_allclose([g.temperature_c for g in got], [w[0] for w in want], atol=1e-9)
    np.testing.assert_allclose([g.rate_c_per_s for g in got], [w[1] for w in want], atol=1e-11)


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


if __name__ == "__main__":  # the figures quoted in docs/model.md
    import sys

    for seed in [int(a) for a in sys.argv[1:]] or [SEED]:
        for name, sensor in (("0.01 C / 0.1 s", FINE), ("0.125 C / 1.28 s", COARSE)):
            for c in compare(sensor, seed):
                print(f"seed {seed}  {name:16}  {c.run}:  Kalman {c.kalman_c:.3f} C   "
                      f"centred {c.centred_c:.3f} C (W={c.centred_window_p}P, "
                      f"ratio {c.kalman_c / c.centred_c:.2f})   backward {c.backward_c:.3f} C "
                      f"(W={c.backward_window_p}P, ratio {c.kalman_c / c.backward_c:.2f})")


@pytest.mark.parametrize("sensor", [FINE, COARSE], ids=["0.01C-0.1s", "0.125C-1.28s"])
def test_delta_t_beats_the_finite_difference_of_consecutive_readings(
    sensor: tuple[float, float],
) -> None:
    """The issue's baseline: ΔT = τ·(difference of consecutive raw readings)/P.

    Measured (seed 4), Kalman vs consecutive difference, °C RMS: fine sensor
    0.33 vs 17.2 (5 min) and 0.10 vs 17.2 (60 min); coarse sensor 0.75 vs 3.0 and
    0.12 vs 3.5. The stronger, oracle-tuned baselines are compared above.
    """
    lsb_c, period_s = sensor
    gyro = GyroParams(temperature_lsb_c=lsb_c, temperature_period_s=period_s)
    cfg = EstimatorConfig(tau_s=gyro.tau_s, quantisation_c=lsb_c, update_period_s=period_s)
    for run in chamber_runs([5, 60], seed=SEED, rate_hz=5.0, gyro=gyro, hold_s=1200):
        truth = run.extra["true_delta_t_c"]
        kf = _rms(estimate_series(run.time_s, run.temperature_c, cfg).delta_t_c - truth)
        st, sc = _raw_readings(run.time_s, run.temperature_c, period_s)
        fd = _rms(_difference_delta_t(run.time_s, st, sc, period_s, gyro.tau_s,
                                      centred=False) - truth)
        assert kf < 0.3 * fd, (run.name, kf, fd)
