"""The ``offsets`` fit (one switch-on offset per run, 1-s blocks) against hand-built
cases whose answer is known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation import RunFeatures, Scaling, fit, get_model
from gyrotherm.compensation._fit_offsets import (
    block_means,
    choose_method,
    solve_offsets,
    within_run_share,
)
from gyrotherm.estimators import EstimatorConfig

EST = EstimatorConfig()
SCALING = Scaling(t_ref_c=25.0, t_scale_c=10.0, dt_scale_c=2.0)
#: centred coefficients of T², T, ΔT, T·ΔT (°/s) the rates are built from
TRUE = np.array([0.02, -0.05, 0.03, -0.01])


def _run(name: str, t0_c: float, t1_c: float, offset_dps: float, *, rate_hz: float = 10.0,
         duration_s: float = 600.0, rest: np.ndarray | None = None) -> RunFeatures:
    time_s = np.arange(0.0, duration_s, 1.0 / rate_hz)
    sec = np.floor(time_s + 1e-9)  # T, ΔT held for each 1-s block: block means are exact
    temp = t0_c + (t1_c - t0_c) * sec / duration_s + 0.5 * np.sin(sec / 37.0)
    dtemp = 1.5 * np.cos(sec / 53.0)
    x, g = SCALING.centre(temp, dtemp)
    rate = TRUE @ np.vstack([x * x, x, g, x * g]) + offset_dps
    return RunFeatures(name, "hand", "", time_s, temp, dtemp, {"x": rate}, rest=rest)


def test_recovers_the_terms_and_each_runs_offset_exactly() -> None:
    runs = [_run("cold", 5.0, 15.0, +0.20), _run("mid", 20.0, 30.0, -0.10, rate_hz=100.0),
            _run("hot", 35.0, 45.0, +0.05, duration_s=900.0)]
    coef, offsets = solve_offsets(get_model("paper"), SCALING, runs, "x")
    np.testing.assert_allclose(coef[:4], TRUE, atol=1e-12)
    np.testing.assert_allclose(offsets, [0.20, -0.10, 0.05], atol=1e-12)
    assert coef[4] == pytest.approx(np.mean([0.20, -0.10, 0.05]), abs=1e-12)
    # one intercept for all runs passes the offsets into the T terms
    pooled = fit(runs, "paper", estimator=EST, method="pooled", scaling=SCALING)
    assert np.max(np.abs(np.array(pooled.coefficients["x"][:4]) - TRUE)) > 1e-3
    via_fit = fit(runs, "paper", estimator=EST, method="offsets", scaling=SCALING)
    np.testing.assert_allclose(via_fit.coefficients["x"], coef, atol=0)


def test_rows_off_the_rest_mask_do_not_count() -> None:
    rest = np.ones(6000, dtype=bool)
    rest[1000:2500] = False
    moving = _run("moving", 10.0, 40.0, 0.1, rest=rest)
    moving.rates_dps["x"][~rest] += 50.0  # a turn: nothing of it may reach the fit
    still = _run("still", 15.0, 35.0, -0.2)
    coef, offsets = solve_offsets(get_model("paper"), SCALING, [moving, still], "x")
    np.testing.assert_allclose(coef[:4], TRUE, atol=1e-12)
    np.testing.assert_allclose(offsets, [0.1, -0.2], atol=1e-12)
    t, _, y = block_means(moving, "x")
    assert len(t) == 600 - 150 and np.all(y < 10.0)


def test_block_means_are_one_second_means_of_time_since_the_first_row() -> None:
    run = _run("r", 20.0, 20.0, 0.0, rate_hz=4.0, duration_s=3.0)
    t, _, _ = block_means(run, "x")
    np.testing.assert_allclose(t, [run.temperature_c[i:i + 4].mean() for i in (0, 4, 8)])
    np.testing.assert_allclose(t, run.temperature_c[[0, 4, 8]])


def test_a_run_without_temperature_change_within_it_cannot_carry_the_terms() -> None:
    flat = [_run(f"r{i}", 20.0 + i, 20.0 + i, 0.0) for i in range(3)]
    flat = [RunFeatures(r.name, r.source, "", r.time_s, np.full(len(r.time_s), 20.0 + i),
                        np.zeros(len(r.time_s)), r.rates_dps) for i, r in enumerate(flat)]
    with pytest.raises(CalibrationError, match=r"not identifiable .* one offset per run"):
        solve_offsets(get_model("paper"), SCALING, flat, "x")


def test_auto_picks_offsets_for_runs_spanning_temperature_and_pooled_for_plateaus() -> None:
    ramps = [_run("a", 5.0, 45.0, 0.1), _run("b", 10.0, 40.0, -0.1)]
    method, share = choose_method(ramps)
    assert method == "offsets" and share > 0.8
    plateaus = [_run("cold", 15.0, 15.0, 0.0), _run("hot", 40.0, 40.0, 0.0)]
    method, share = choose_method(plateaus)  # ±0.5 °C wiggle within, 25 °C between
    assert method == "pooled" and share < 0.01
    # hand-computed: two runs of block temperatures {0, 2} and {10, 12}: within 4, total 104
    a = RunFeatures("a", "hand", "", np.array([0.0, 1.0]), np.array([0.0, 2.0]),
                    np.zeros(2), {"x": np.zeros(2)})
    b = RunFeatures("b", "hand", "", np.array([0.0, 1.0]), np.array([10.0, 12.0]),
                    np.zeros(2), {"x": np.zeros(2)})
    assert within_run_share([a, b]) == pytest.approx(4.0 / 104.0)
    assert within_run_share([a]) == 1.0


@pytest.mark.parametrize("method", ["offsets", "pooled", "paper-average"])
def test_no_row_at_rest_is_a_clear_error_not_a_traceback(method: str) -> None:
    # a 31-s PX4 log (sample_px4_events.ulg of the real-log corpus) left no row at rest,
    # and `fit --force` went on to a numpy ValueError on an empty array
    run = _run("moving", 10.0, 40.0, 0.0, rest=np.zeros(6000, dtype=bool))
    with pytest.raises(CalibrationError, match=r"no row to fit in runs \['moving'\]: rest "
                                               r"detection kept none"):
        fit([run], "paper", estimator=EST, method=method)  # type: ignore[arg-type]
    assert choose_method([run]) == ("pooled", 0.0)
