"""The daemon's estimator (``engine="python"``, float arithmetic) against the reference,
the same :class:`TemperatureEstimator` on filterpy's ``KalmanFilter`` (``engine="filterpy"``).

Every field of every :class:`TemperatureEstimate` (T, Ṫ, ΔT, their standard deviations,
time, stale, rejected, updates) and every counter must agree, floats to 1e-9: over a
simulated chamber run as the daemon sees it (10 Hz quantised readings, a dropout with
predict-only steps, a spike, a step, a time base stepping back), and over arbitrary
sequences of calls with arbitrary floats.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from gyrotherm._errors import ConfigError
from gyrotherm.estimators import EstimatorConfig, TemperatureEstimate, TemperatureEstimator
from gyrotherm.estimators._temperature import MAX_PREDICT_S
from gyrotherm.sim import GyroParams, chamber_runs

FLOAT_FIELDS = ("time_s", "temperature_c", "rate_c_per_s", "delta_t_c", "temperature_std_c",
                "rate_std_c_per_s", "delta_t_std_c")
COUNTERS = ("rejected_total", "reinitialisations", "time_resets", "non_finite_resets")


def assert_same(got: TemperatureEstimate, want: TemperatureEstimate, *, rtol: float = 0.0,
                where: object = None) -> None:
    for name in FLOAT_FIELDS:
        a, b = getattr(got, name), getattr(want, name)
        assert (a == b or (math.isnan(a) and math.isnan(b))  # also ±inf times, NaN states
                or abs(a - b) <= 1e-9 + rtol * abs(b)), (where, name, a, b)
    assert (got.stale, got.rejected, got.updates) == (want.stale, want.rejected, want.updates), (
        where, got, want)


def assert_same_counters(got: TemperatureEstimator, want: TemperatureEstimator) -> None:
    assert [getattr(got, c) for c in COUNTERS] == [getattr(want, c) for c in COUNTERS]


def daemon_view_of_a_chamber_run() -> tuple[EstimatorConfig, list[tuple[str, float, float]]]:
    """A simulated 20-min heating run (−20 → 50 °C, the simulator's quantised, noisy
    10 Hz sensor) as the daemon's pipeline feeds it: ``update`` per temperature frame;
    a 30-s dropout in which the pipeline calls ``predict`` (1 Hz); a 40 °C spike; a
    real 8 °C step (re-initialisation after repeated rejections); the time base
    stepping back 100 s (a time reset); non-finite readings."""
    gyro = GyroParams()
    run = chamber_runs([20], seed=5, rate_hz=10.0, gyro=gyro, hold_s=600)[0]
    t = np.asarray(run.time_s, dtype=float).copy()
    z = np.asarray(run.temperature_c, dtype=float).copy()
    n = len(t)
    z[n // 5] += 40.0                     # a spike
    z[n // 2:] += 8.0                     # a real step
    t[3 * n // 4:] -= 100.0               # the time base steps back
    z[[n // 3, n // 3 + 7]] = [math.nan, math.inf]
    dropout = (t > 500.0) & (t < 530.0)
    ops: list[tuple[str, float, float]] = []
    next_predict_s = 500.0
    for ti, zi, gone in zip(t.tolist(), z.tolist(), dropout.tolist(), strict=True):
        if gone:
            if ti >= next_predict_s:
                ops.append(("predict", ti, math.nan))
                next_predict_s += 1.0
            continue
        ops.append(("update", ti, zi))
    cfg = EstimatorConfig(tau_s=gyro.tau_s, noise_c=gyro.temperature_noise_c,
                          quantisation_c=gyro.temperature_lsb_c,
                          update_period_s=gyro.temperature_period_s)
    return cfg, ops


def run_ops(est: TemperatureEstimator,
            ops: list[tuple[str, float, float]]) -> list[TemperatureEstimate]:
    out = []
    for op, t, z in ops:
        if op == "update":
            out.append(est.update(t, z))
        elif op == "predict":
            out.append(est.predict(t))
        elif op == "reset":
            est.reset()
            out.append(est.estimate())
        else:
            out.append(est.estimate(t))
    return out


def test_the_default_engine_is_the_float_one() -> None:
    assert TemperatureEstimator().engine == "python"
    assert TemperatureEstimator(engine="filterpy").engine == "filterpy"
    with pytest.raises(ConfigError, match="engine"):
        TemperatureEstimator(engine="numpy")  # type: ignore[arg-type]


def test_a_chamber_run_as_the_daemon_sees_it_equals_filterpy() -> None:
    cfg, ops = daemon_view_of_a_chamber_run()
    ours, ref = TemperatureEstimator(cfg), TemperatureEstimator(cfg, engine="filterpy")
    got, want = run_ops(ours, ops), run_ops(ref, ops)
    for i, (g, w) in enumerate(zip(got, want, strict=True)):
        assert_same(g, w, where=(i, ops[i]))
    assert_same_counters(ours, ref)
    # the run went through what it was built to exercise
    assert ref.rejected_total >= 7 and ref.reinitialisations == 1 and ref.time_resets == 1
    assert sum(op == "predict" for op, _, _ in ops) >= 29
    assert any(w.stale for w in want) and want[-1].updates > 1000
    # and the estimate is the physical one: T tracks the reading, ΔT within 5 °C
    assert abs(want[-1].temperature_c - ops[-1][2]) < 0.2 and abs(want[-1].delta_t_c) < 5.0
    # most rows are not merely close but equal: the same operations in the same order
    same = sum(g.temperature_c == w.temperature_c for g, w in zip(got, want, strict=True))
    assert same >= 0.5 * len(got)


times = st.one_of(st.sampled_from([0.0, 1.0, 1e6, MAX_PREDICT_S, 1e300, -1e300, math.nan,
                                   math.inf, -math.inf]),
                  st.floats(-1e3, 1e3), st.floats(allow_nan=True, allow_infinity=True))
readings = st.one_of(st.sampled_from([20.0, 1e308, -1e308, 5e-324, math.nan, math.inf]),
                     st.floats(-40.0, 125.0), st.floats(allow_nan=True, allow_infinity=True))
ops_strategy = st.lists(st.tuples(st.sampled_from(["update", "update", "predict", "estimate",
                                                   "reset"]), times, readings), max_size=60)


@settings(derandomize=True, max_examples=400, deadline=None, database=None,
          phases=(Phase.explicit, Phase.generate, Phase.shrink))
@given(ops=ops_strategy, period_s=st.sampled_from([0.0, 0.5]))
def test_any_calls_give_the_same_estimates_as_filterpy(
    ops: list[tuple[str, float, float]], period_s: float,
) -> None:
    cfg = EstimatorConfig(update_period_s=period_s)
    ours, ref = TemperatureEstimator(cfg), TemperatureEstimator(cfg, engine="filterpy")
    for i, (g, w) in enumerate(zip(run_ops(ours, ops), run_ops(ref, ops), strict=True)):
        assert_same(g, w, rtol=1e-12, where=(i, ops[: i + 1]))
    assert_same_counters(ours, ref)
