"""Rest detection and masked fits: simulator runs with rotations injected at known times."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run
from gyrotherm.compensation import RunFeatures, features, fit, score
from gyrotherm.compensation._rest import RestConfig, detect_rest, rest_of_run
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs
from motionkit import with_rotations

ROTATIONS_S = ((900.0, 930.0), (1500.0, 1560.0), (2600.0, 2606.0), (3300.0, 3420.0))
GYRO = GyroParams()
EST = EstimatorConfig(tau_s=GYRO.tau_s)


@pytest.fixture(scope="module")
def still_runs() -> list[Run]:
    return chamber_runs([10, 30, 60], seed=7, rate_hz=10.0, hold_s=1500.0)


def _excluded_spans(rest: np.ndarray, t: np.ndarray) -> list[tuple[float, float]]:
    edges = np.diff(np.concatenate(([0], (~rest).astype(np.int8), [0])))
    return [(float(t[a]), float(t[b - 1]))
            for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1),
                            strict=True)]


def test_detected_motion_matches_the_injected_intervals(still_runs: list[Run]) -> None:
    moving = with_rotations(still_runs[1], ROTATIONS_S)
    report = rest_of_run(moving)
    spans = _excluded_spans(report.rest, moving.time_s)
    assert len(spans) == len(ROTATIONS_S)
    cfg = RestConfig()
    tol = cfg.window_s + cfg.guard_s + 0.2  # one block, plus the guard, plus a row
    for (a, b), (lo, hi) in zip(ROTATIONS_S, spans, strict=True):
        assert lo <= a <= lo + tol and hi - tol <= b <= hi + tol
    assert [(s.start_s, s.end_s) for s in report.segments] == spans
    assert all("rate variance" in s.reasons for s in report.segments)
    expected = sum(hi - lo + 0.1 for lo, hi in spans)
    assert report.excluded_s == pytest.approx(expected, abs=1e-6)
    assert report.excluded_fraction == pytest.approx(np.mean(~report.rest))
    # the noise estimate is the simulator's white noise: N/60·√f_s
    white = GYRO.arw_deg_per_rth / 60.0 * np.sqrt(10.0)
    for axis in "xyz":
        assert report.noise_dps[axis] == pytest.approx(white, rel=0.1)


def test_runs_at_rest_lose_no_row(still_runs: list[Run]) -> None:
    for run in still_runs:
        assert rest_of_run(run).rest.all()
    quiet = chamber_runs([10], seed=2, rate_hz=10.0, hold_s=600.0, gyro=GYRO.quiet())[0]
    assert rest_of_run(quiet).rest.all()  # noise-free: the rate floor keeps it at rest


def test_accelerometer_alone_marks_motion(still_runs: list[Run]) -> None:
    run = with_rotations(still_runs[0], ((1000.0, 1040.0),), accel=True)
    shaken_only = Run(name="shaken", time_s=run.time_s, temperature_c=run.temperature_c,
                      rates_dps=still_runs[0].rates_dps, extra=run.extra)
    report = rest_of_run(shaken_only)
    assert [s.reasons for s in report.segments] == [("accel variance", "guard")]
    (lo, hi), = _excluded_spans(report.rest, run.time_s)
    assert lo <= 1000.0 <= lo + 2.2 and hi - 2.2 <= 1040.0 <= hi + 2.2


def test_short_rest_between_turns_is_excluded() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(0, 600, 0.1)
    x = rng.standard_normal(len(t)) * 0.05
    x[(t >= 200) & (t < 210)] += 30.0
    x[(t >= 220) & (t < 230)] += 30.0  # 10 s of rest in between: shorter than 30 s
    report = detect_rest(t, {"x": x})
    (lo, hi), = _excluded_spans(report.rest, t)
    assert lo == pytest.approx(199.0, abs=1.1) and hi == pytest.approx(230.9, abs=1.1)
    assert "short rest" in report.segments[0].reasons


def test_masked_fit_matches_truth_as_well_as_the_motion_free_fit(
    still_runs: list[Run],
) -> None:
    moving = [with_rotations(r, ROTATIONS_S, seed=i) for i, r in enumerate(still_runs)]
    still = [features(r, EST) for r in still_runs]
    unmasked = [features(r, EST) for r in moving]
    masked = [replace(f, rest=rest_of_run(r).rest) for f, r in zip(unmasked, moving,
                                                                    strict=True)]
    assert all(f.rest is not None and not f.rest.all() for f in masked)

    def truth_rms(feats: list[RunFeatures]) -> float:
        cal = fit(feats, "paper", estimator=EST)
        # scored against the true bias on every row of the motion-free runs
        return float(np.mean([s.truth.rms_dps for f in still for s in score(cal, f)
                              if s.truth is not None]))

    ref, good, bad = truth_rms(still), truth_rms(masked), truth_rms(unmasked)
    assert good <= 1.2 * ref + 1e-3
    assert bad > 10 * ref
    cal = fit(masked, "paper", estimator=EST)
    for entry, f in zip(cal.provenance["runs"], masked, strict=True):
        assert f.rest is not None and entry["rest_rows"] == int(f.rest.sum())


def test_bad_settings_and_too_short_runs_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"rest\.window_s"):
        RestConfig(window_s=0.0)
    with pytest.raises(ConfigError, match=r"rest\.min_rows"):
        RestConfig(min_rows=1)
    with pytest.raises(ConfigError, match="too few for rest detection"):
        detect_rest(np.arange(5.0), {"x": np.zeros(5)}, name="tiny")


def test_a_long_constant_rate_turn_is_motion() -> None:
    """A turntable at 5 °/s for 120 s, edges on block boundaries: no variance anywhere
    and no offset against its own running median; the level change gives it away."""
    rng = np.random.default_rng(3)
    t = np.arange(0, 900, 0.1)
    rates = {a: rng.standard_normal(len(t)) * 0.05 for a in "xyz"}
    turn = (t >= 300) & (t < 420)
    rates["z"][turn] += 5.0
    report = detect_rest(t, rates)
    (lo, hi), = _excluded_spans(report.rest, t)
    assert 298.9 <= lo <= 300.0 and 419.9 <= hi <= 422.0  # ± one block and the guard
    assert "rate offset" in report.segments[0].reasons


def test_a_fast_linear_drift_is_not_motion_at_the_ends_but_a_turn_still_is() -> None:
    """A bias drifting 0.6 °/s per minute (a fast power-on ramp) under 0.002 °/s noise at
    2 Hz: a window that went one-sided at the ends of the log lagged it by
    0.01 °/s/s × 10 s = 0.1 °/s > 0.05 and called the first and last 10 s motion. (The
    drift is on x only: on three axes it would reach 7.8 °/s in magnitude, past the
    5-°/s physical limit of a gyro at rest.)"""
    rng = np.random.default_rng(11)
    t = 5.0 + np.arange(900) * 0.5
    drift = {"x": 0.01 * (t - t[0]), "y": 0.0 * t, "z": 0.0 * t}
    rates = {a: drift[a] + rng.standard_normal(len(t)) * 0.002 for a in "xyz"}
    assert detect_rest(t, rates).segments == ()
    turn = (t >= 200.0) & (t < 230.0)
    rates["x"] = rates["x"] + np.where(turn, 20.0 * np.sin(np.pi * (t - 200.0) / 30.0), 0.0)
    report = detect_rest(t, rates)
    (lo, hi), = _excluded_spans(report.rest, t)
    # the turn is found; beside it the window is one-sided again, and this drift
    # (far faster than a thermal one) widens the segment: by ≤ 30 s here
    assert 170.0 <= lo <= 200.0 and 229.5 <= hi <= 260.0
    assert report.excluded_s < 30.0 + 60.0


def test_a_turn_that_starts_the_log_is_dropped_at_the_default_min_segment() -> None:
    """The running median is centred at the ends, so a constant-rate turn at t = 0 shows no
    offset; its stop is a step, and the stretch before it is shorter than the 30-s
    minimum: excluded as "short rest" (docs/export.md, the limits)."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 600.0, 0.1)
    rates = {a: rng.standard_normal(len(t)) * 0.01 for a in "xyz"}
    rates["x"][t < 10.0] += 0.5
    report = detect_rest(t, rates)
    (lo, hi), = _excluded_spans(report.rest, t)
    assert lo == 0.0 and 10.0 <= hi <= 12.5
    assert "short rest" in report.segments[0].reasons
