"""The estimator takes any float time stamp and reading without raising, and keeps a
finite state (module docstring of gyrotherm.estimators._temperature, "Robustness")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from gyrotherm.estimators import EstimatorConfig, TemperatureEstimator
from gyrotherm.estimators._temperature import ENGINES, MAX_PREDICT_S, Engine

EXTREME = [1e300, -1e300, 1e308, -1e308, 5e-324, -5e-324, 0.0, math.nan, math.inf, -math.inf,
           1e6, -1e6, MAX_PREDICT_S, 2 * MAX_PREDICT_S]
SANE_START_S = 1e4


def _assert_finite(est: TemperatureEstimator) -> None:
    if not est.initialised:
        return
    x, p = est._state(), est._covariance()  # the private state: what the guarantee is about
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(p)), (x, p)
    if est.engine == "filterpy":  # and filterpy's own matrices (what the state copies)
        assert np.all(np.isfinite(est._kf.x)) and np.all(np.isfinite(est._kf.P))
    e = est.estimate()
    assert all(math.isfinite(v) for v in (e.temperature_c, e.rate_c_per_s, e.delta_t_c,
                                          e.temperature_std_c, e.delta_t_std_c))


times = st.one_of(st.sampled_from(EXTREME),
                  st.floats(SANE_START_S - 1e3, SANE_START_S + 1e3),
                  st.floats(allow_nan=True, allow_infinity=True))
readings = st.one_of(st.sampled_from([20.0, 1e308, -1e308, 5e-324, math.nan, math.inf]),
                     st.floats(-40.0, 125.0), st.floats(allow_nan=True, allow_infinity=True))
ops = st.lists(st.tuples(st.sampled_from(["update", "predict", "estimate"]), times, readings),
               max_size=40)


@pytest.mark.parametrize("engine", ENGINES)
@settings(derandomize=True, max_examples=300, deadline=None, database=None,
          phases=(Phase.explicit, Phase.generate, Phase.shrink))
@given(ops=ops)
def test_any_stamps_and_readings_never_raise_and_keep_the_state_finite(
    engine: Engine, ops: list[tuple[str, float, float]],
) -> None:
    est = TemperatureEstimator(EstimatorConfig(tau_s=120.0), engine=engine)
    for op, t, reading in ops:
        if op == "update":
            est.update(t, reading)
        elif op == "predict":
            e = est.predict(t)
            if est.initialised and not math.isfinite(t):
                assert e.stale  # a non-finite "now" is never fresh
        else:
            est.estimate(t)
        _assert_finite(est)
    # then a sane, flat 20 °C stream: after at most max_consecutive_rejections + 1
    # readings the filter runs on it (re-initialised or never disturbed), and after 30
    # it reads 20 °C, fresh
    cfg = est.config
    out = None
    for k in range(30):
        out = est.update(SANE_START_S + 2e6 + k, 20.0)  # beyond any garbage stamp above
        _assert_finite(est)
        if k == cfg.max_consecutive_rejections:
            assert out.updates >= 1 and not out.rejected
    assert out is not None
    assert out.temperature_c == pytest.approx(20.0, abs=0.05)
    assert abs(out.delta_t_c) < 1.0
    assert not out.stale


@pytest.mark.parametrize("engine", ENGINES)
def test_a_reading_beyond_max_predict_s_reinitialises_instead_of_overflowing(
    engine: Engine,
) -> None:
    est = TemperatureEstimator(engine=engine)
    for k in range(10):
        est.update(float(k), 20.0 + 0.01 * k)
    out = est.update(9.0 + MAX_PREDICT_S + 1.0, 30.0)  # dt**3 would be 1e18+: no predict
    assert est.time_resets == 1 and out.updates == 1 and out.temperature_c == 30.0
    out = est.update(1e300, 30.0)  # the old code raised OverflowError here (dt**3)
    assert est.time_resets == 2 and out.temperature_c == 30.0
    _assert_finite(est)


@pytest.mark.parametrize("engine", ENGINES)
def test_predict_beyond_max_predict_s_holds_the_state_and_says_stale(engine: Engine) -> None:
    est = TemperatureEstimator(engine=engine)
    for k in range(10):
        est.update(float(k), 20.0)
    held = est.estimate()
    out = est.predict(1e300)
    assert out.stale and out.temperature_c == held.temperature_c
    assert out.temperature_std_c == held.temperature_std_c  # no covariance blow-up
    inside = est.predict(9.0 + 1000.0)  # a long but allowed prediction: P grows, finite
    assert inside.temperature_std_c > held.temperature_std_c
    _assert_finite(est)


def test_reset_forgets_the_state_and_the_next_reading_initialises() -> None:
    est = TemperatureEstimator()
    for k in range(10):
        est.update(float(k), 20.0)
    est.reset()
    assert not est.initialised and math.isnan(est.estimate().temperature_c)
    out = est.update(-5.0, 25.0)
    assert out.updates == 1 and out.temperature_c == 25.0 and out.time_s == -5.0
