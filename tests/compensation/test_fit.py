"""Fitting: recovery of simulator truth, centring, Table 2's comparison, validation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm import CalibrationError
from gyrotherm.compensation import (
    RunFeatures,
    default_scaling,
    features,
    fit,
    fit_per_run,
    leave_one_out,
    score,
)
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import ChamberModel, GyroParams, chamber_runs


@pytest.fixture(scope="module")
def quiet_setup() -> tuple[GyroParams, EstimatorConfig, list[RunFeatures]]:
    """Noise turned down: no gyro or sensor noise, no offsets, no chamber control noise."""
    gyro = GyroParams().quiet()
    est = EstimatorConfig(tau_s=gyro.tau_s, noise_c=1e-3, quantisation_c=0.0,
                          process_noise_c2_per_s3=1e-5)
    runs = chamber_runs([5, 20, 60], seed=2, rate_hz=2.0, gyro=gyro,
                        chamber=ChamberModel(noise_c=0.0), hold_s=1800)
    return gyro, est, [features(r, est) for r in runs]


def test_pooled_fit_recovers_true_coefficients(quiet_setup) -> None:  # type: ignore[no-untyped-def]
    gyro, est, feats = quiet_setup
    cal = fit(feats, "paper", estimator=est, method="pooled")
    for axis in "xyz":
        got = cal.physical_coefficients(axis)
        for term, true in gyro.bias.coefficients[axis].items():
            assert got[term] == pytest.approx(true, rel=0.01), (axis, term)


def _raw_to_celsius(a: np.ndarray, k0: float, k1: float) -> dict[str, float]:
    """Paper-model coefficients in raw counts R = k0 + k1·T (T in °C) → coefficients in °C."""
    return {"T^2": a[0] * k1**2, "T": 2 * a[0] * k0 * k1 + a[1] * k1, "dT": a[2] + a[3] * k0,
            "T*dT": a[3] * k1, "1": a[0] * k0**2 + a[1] * k0 + a[4]}


def test_centred_fit_keeps_digits_a_naive_uncentred_fit_loses(quiet_setup) -> None:  # type: ignore[no-untyped-def]
    # Raw units: temperature in centi-kelvin, R = 27315 + 100·T, as a sensor log may hold it
    # (the paper also fitted raw values: Table 1's a5 ≈ 10^4). Both fits see the same data.
    gyro, est, feats = quiet_setup
    truth = gyro.bias.coefficients["x"]
    k0, k1 = 27315.0, 100.0
    raw = [replace(f, temperature_c=k0 + k1 * f.temperature_c) for f in feats]
    centred_raw = fit(raw, "paper", estimator=est).physical_coefficients("x")
    centred = _raw_to_celsius(np.array(list(centred_raw.values())), k0, k1)
    # Naive: the uncentred design in raw units, solved by least squares as-is.
    r = np.concatenate([f.temperature_c for f in raw])
    d = np.concatenate([f.delta_t_c for f in raw])
    y = np.concatenate([f.rates_dps["x"] for f in raw])
    a = np.column_stack([r**2, r, d, r * d, np.ones_like(r)])
    naive = _raw_to_celsius(np.linalg.lstsq(a, y, rcond=None)[0], k0, k1)
    assert np.linalg.cond(a) > 1e11
    centred_err = max(abs(centred[k] / truth[k] - 1) for k in truth)
    naive_err = max(abs(naive[k] / truth[k] - 1) for k in truth)
    assert centred_err < 0.01
    assert naive_err > 10 * centred_err


def test_paper_model_beats_single_run_t2_on_validation_as_in_table2(
    paper_features: list[RunFeatures], validation_features: RunFeatures,
    estimator: EstimatorConfig,
) -> None:
    scaling = default_scaling(paper_features)
    paper = {m: score(fit(paper_features, "paper", estimator=estimator, method=m,
                          scaling=scaling), validation_features)
             for m in ("paper-average", "pooled")}
    for i in (0, 5, 6):  # the paper's 1st, 6th and 7th set: 5, 50, 60 min heating
        t2 = score(fit([paper_features[i]], "t2", estimator=estimator, scaling=scaling),
                   validation_features)
        for method, scores in paper.items():
            rms_paper = np.mean([s.compensated.rms_dps for s in scores])
            rms_t2 = np.mean([s.compensated.rms_dps for s in t2])
            assert rms_paper < rms_t2, (method, i, rms_paper, rms_t2)
            # and against simulator truth, by a wide margin
            truth_paper = np.mean([s.truth.rms_dps for s in scores if s.truth])
            truth_t2 = np.mean([s.truth.rms_dps for s in t2 if s.truth])
            assert truth_paper < 0.6 * truth_t2
    # compensation improves the raw output by about an order of magnitude (the paper's claim)
    s = paper["paper-average"]
    assert np.mean([x.raw.rms_dps for x in s]) > 5 * np.mean([x.compensated.rms_dps for x in s])


def test_paper_average_is_mean_of_per_run_fits(
    paper_features: list[RunFeatures], estimator: EstimatorConfig
) -> None:
    scaling = default_scaling(paper_features)
    per_run = fit_per_run(paper_features, "paper", estimator=estimator, scaling=scaling)
    avg = fit(paper_features, "paper", estimator=estimator, method="paper-average",
              scaling=scaling)
    for axis in "xyz":
        table1 = np.array([list(c.physical_coefficients(axis).values()) for c in per_run])
        np.testing.assert_allclose(list(avg.physical_coefficients(axis).values()),
                                   table1.mean(axis=0), rtol=1e-9)


def test_leave_one_run_out_scores_every_run_with_a_fit_without_it(
    paper_features: list[RunFeatures], estimator: EstimatorConfig
) -> None:
    calls: list[tuple[int, int]] = []
    held = leave_one_out(paper_features[:4], "paper", estimator=estimator,
                         progress=lambda i, n: calls.append((i, n)))
    assert [h.run for h in held] == [f.name for f in paper_features[:4]]
    assert calls[-1] == (4, 4)
    for h in held:
        assert {s.axis for s in h.scores} == {"x", "y", "z"}
        for s in h.scores:
            assert s.compensated.rms_dps < 0.3 * s.raw.rms_dps


def test_temperature_only_data_cannot_identify_delta_t_terms(estimator: EstimatorConfig) -> None:
    # A run that never heats has no ΔT variation: the paper model is not identifiable.
    from gyrotherm.sim import ChamberProfile, simulate

    flat = ChamberProfile.from_pairs([(0.0, 25.0), (1200.0, 25.0)])
    run = simulate(flat, name="flat", gyro=GyroParams().quiet(), rate_hz=1.0,
                   chamber=ChamberModel(noise_c=0.0))
    with pytest.raises(CalibrationError, match="not identifiable"):
        fit([features(run, estimator)], "paper", estimator=estimator)


def test_outside_the_calibrated_range_is_clamped_and_flagged(
    paper_features: list[RunFeatures], estimator: EstimatorConfig
) -> None:
    cal = fit(paper_features, "paper", estimator=estimator)
    r = cal.valid_range
    inside = cal.bias_at(20.0, 0.0)
    assert not inside.t_clamped and not inside.dt_clamped
    hot = cal.bias_at(r.t_max_c + 30.0, 0.0)
    edge = cal.bias_at(r.t_max_c, 0.0)
    assert hot.t_clamped and not hot.dt_clamped
    assert hot.bias_dps == edge.bias_dps  # clamped, not extrapolated
    cold = cal.bias_at(20.0, r.dt_min_c - 5.0)
    assert cold.dt_clamped and not cold.t_clamped
    bias, clamped = cal.bias_series("x", np.array([20.0, r.t_max_c + 1]), np.zeros(2))
    assert list(clamped) == [False, True]
    assert bias[0] == pytest.approx(inside.bias_dps["x"])


@pytest.mark.parametrize("block_rows", [7, 1 << 16])
def test_blockwise_solve_equals_lstsq(monkeypatch: pytest.MonkeyPatch, block_rows: int) -> None:
    """The blockwise QR least squares (bounded memory on long logs) gives numpy's
    lstsq solution on the stacked design matrix, across runs and block edges."""
    from gyrotherm.compensation import _fit
    from gyrotherm.compensation._models import Scaling, get_model

    monkeypatch.setattr(_fit, "_BLOCK_ROWS", block_rows)
    rng = np.random.default_rng(11)
    runs = []
    for i, n in enumerate((50, 123, 9)):
        t = rng.uniform(-20, 50, n)
        d = rng.normal(0, 2, n)
        y = 0.3 - 0.01 * t + 1e-4 * t**2 + 0.05 * d - 4e-4 * t * d + rng.normal(0, 0.01, n)
        runs.append(_fit.RunFeatures(name=f"r{i}", source="mem", sha256="", time_s=np.arange(n),
                                     temperature_c=t, delta_t_c=d, rates_dps={"x": y}))
    spec, scaling = get_model("paper"), Scaling(15.0, 35.0, 2.0)
    got = _fit._solve(spec, scaling, runs, "x")
    t = np.concatenate([r.temperature_c for r in runs])
    d = np.concatenate([r.delta_t_c for r in runs])
    y = np.concatenate([r.rates_dps["x"] for r in runs])
    want = np.linalg.lstsq(spec.design(*scaling.centre(t, d)), y, rcond=None)[0]
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-13)
    flat = [_fit.RunFeatures(name="flat", source="mem", sha256="", time_s=np.arange(40),
                             temperature_c=np.full(40, 20.0), delta_t_c=rng.normal(0, 1, 40),
                             rates_dps={"x": rng.normal(0, 1, 40)})]
    rank = np.linalg.lstsq(spec.design(*scaling.centre(flat[0].temperature_c,
                                                       flat[0].delta_t_c)),
                           flat[0].rates_dps["x"], rcond=None)[2]
    assert rank == 2  # T constant: {T², T, 1} and {ΔT, T·ΔT} collapse to one column each
    with pytest.raises(CalibrationError, match="design rank 2 < 5"):
        _fit._solve(spec, scaling, flat, "x")
