"""Least-squares fitting of bias models to runs, and leave-one-run-out validation.

Per run r with rows i, the estimator (the same one the daemon runs) turns the
temperature readings into T_i and ΔT_i; the design matrix A_r holds the model's
terms in centred variables and the fit solves min ‖A_r c − y_r‖² per axis
(``numpy.linalg.lstsq``, an SVD: no normal equations, no squared condition
number). Methods:

* ``offsets`` (``gyrotherm fit``'s default; this module's functions default to
  ``pooled``, as before): one least-squares fit over all runs on 1-s blocks with one
  switch-on offset per run, the constant term their mean
  (:mod:`gyrotherm.compensation._fit_offsets`; what ``diagnose --calibration`` fits);
* ``pooled``: one least-squares fit over the rows of all runs stacked, one intercept;
* ``paper-average``: Tang et al.'s eq. (12): the mean of the per-run
  coefficient vectors (Table 1 → eq. 12 is exactly that column mean). With a
  common scaling the mean of centred coefficients equals the mean of the
  physical ones, since the map between them is linear.

Rows at rest only (logs with motion): a run's ``rest`` mask (from
:func:`gyrotherm.compensation._rest.detect_rest`) keeps T and ΔT estimated over the
whole run but drops the masked rows from the least squares, the ranges, the scaling
and the scores: min Σ_{i: rest_i} (A_i c − y_i)². Without a mask every row counts.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from gyrotherm import __version__
from gyrotherm._errors import CalibrationError
from gyrotherm.codecs import Run
from gyrotherm.compensation._calibration import Calibration, ValidRange
from gyrotherm.compensation._fit_offsets import solve_offsets, solve_triangular_checked
from gyrotherm.compensation._metrics import ErrorMetrics, RunScore
from gyrotherm.compensation._models import ModelSpec, Scaling, get_model
from gyrotherm.compensation._zero import ZeroConfig, ZeroSeries, zero_series
from gyrotherm.estimators import EstimatorConfig, estimate_series

FloatArray = NDArray[np.float64]
_G = TypeVar("_G", bound=np.generic)
Method = Literal["offsets", "pooled", "paper-average"]
METHODS: tuple[Method, ...] = ("offsets", "pooled", "paper-average")


@dataclass(frozen=True)
class RunFeatures:
    """A run turned into model inputs: estimated T and ΔT (°C) and raw rates (°/s)."""

    name: str
    source: str
    sha256: str
    time_s: FloatArray
    temperature_c: FloatArray
    delta_t_c: FloatArray
    rates_dps: Mapping[str, FloatArray]
    true_bias_dps: Mapping[str, FloatArray] = field(default_factory=dict)
    rest: NDArray[np.bool_] | None = None
    """Rows that feed the fit and the scores (True = at rest); None = every row."""

    @property
    def axes(self) -> tuple[str, ...]:
        return tuple(self.rates_dps)

    def rows(self, values: NDArray[_G]) -> NDArray[_G]:
        """``values`` (one per row) restricted to the rest rows."""
        return values if self.rest is None else values[self.rest]


def features(run: Run, estimator: EstimatorConfig) -> RunFeatures:
    """Estimate T and ΔT along ``run`` with the online estimator.

    Fed as the daemon is: with ``estimator.update_period_s == 0`` and a run that
    records its sensor's refresh period (metadata ``temperature_period_s``, written
    by the simulator), each reading is fused once, on the row where it appears —
    one temperature frame per period, as ``gyrotherm sim stream`` plays the run —
    instead of once per row (a 50 Hz run of a 10 Hz sensor would fuse every
    reading five times). A positive ``update_period_s`` overrides the run's period.
    """
    period = run.temperature_period_s()
    if estimator.update_period_s == 0 and period:
        estimator = replace(estimator, update_period_s=period)
    est = estimate_series(run.time_s, run.temperature_c, estimator)
    return RunFeatures(
        name=run.name,
        source=run.source,
        sha256=run.sha256,
        time_s=run.time_s,
        temperature_c=est.temperature_c,
        delta_t_c=est.delta_t_c,
        rates_dps=run.rates_dps,
        true_bias_dps=run.true_bias_dps,
    )


def common_axes(runs: Sequence[RunFeatures]) -> tuple[str, ...]:
    if not runs:
        raise CalibrationError("no runs to fit")
    axes = [a for a in ("x", "y", "z") if all(a in r.rates_dps for r in runs)]
    if not axes:
        raise CalibrationError("the runs share no rate axis")
    return tuple(axes)


_BLOCK_ROWS = 1 << 16
"""Rows of the design matrix formed at a time (bounded memory on long logs)."""


def _solve(spec: ModelSpec, scaling: Scaling, runs: Sequence[RunFeatures], axis: str) -> FloatArray:
    """Least squares of the raw rate on the model's terms, over every row of ``runs``
    (the rest rows of runs with a rest mask).

    Blockwise Householder QR: the (k+1)-column matrix ``[A | y]`` is reduced one
    block of rows at a time, ``R ← qr([[R], [A_block | y_block]])``, so only the
    triangular ``R`` ((k+1)×(k+1)) and one block live at once; the last column of
    ``R`` is ``Qᵀy`` and ``R[:k, :k] c = Qᵀy[:k]`` gives the same solution as
    ``lstsq(A, y)`` (to rounding). Rank: the singular values of ``R[:k, :k]`` (those
    of ``A``) against ``lstsq``'s default cut ``max(n, k)·ε·σ_max``.
    """
    k = len(spec.terms)
    r = np.zeros((0, k + 1))
    n = 0
    for run in runs:
        rate = run.rates_dps[axis]
        for start in range(0, len(rate), _BLOCK_ROWS):
            stop = start + _BLOCK_ROWS
            keep = slice(None) if run.rest is None else run.rest[start:stop]
            a = spec.design(*scaling.centre(run.temperature_c[start:stop][keep],
                                            run.delta_t_c[start:stop][keep]))
            block = np.column_stack([a, rate[start:stop][keep]])
            r = cast(FloatArray, np.linalg.qr(np.vstack([r, block]), mode="r"))
            n += len(block)
    if n < 2 * k:
        raise CalibrationError(f"model {spec.name!r} needs at least {2 * k} rows, got {n}")
    return solve_triangular_checked(
        r, k, n, lambda rank: (
            f"model {spec.name!r} is not identifiable from runs "
            f"{[x.name for x in runs]}: design rank {rank} < {k} terms "
            "(e.g. no temperature change, or no ΔT variation for a ΔT model)"))


def mean_coefficients(per_run: Sequence[FloatArray]) -> FloatArray:
    """Tang et al.'s eq. (12): the element-wise mean of per-run coefficient vectors.

    All vectors must share one scaling; the mean then commutes with the
    (linear) map to physical units, so it equals the mean of Table 1's columns.
    """
    stacked = np.vstack([np.asarray(c, dtype=np.float64) for c in per_run])
    return np.asarray(stacked.mean(axis=0), dtype=np.float64)


def _extremes(runs: Sequence[RunFeatures]) -> tuple[FloatArray, FloatArray]:
    """Per run (rest rows, runs with none left out): [T min, T max] and [ΔT min, ΔT max]
    — what the range and the scaling need, without concatenating long logs. No row at
    all: :class:`CalibrationError` naming the runs (nothing to fit or scale)."""
    t, d = [], []
    for r in runs:
        rt, rd = r.rows(r.temperature_c), r.rows(r.delta_t_c)
        if len(rt):
            t += [float(rt.min()), float(rt.max())]
            d += [float(rd.min()), float(rd.max())]
    if not t:
        raise CalibrationError(
            f"no row to fit in runs {[r.name for r in runs]}: "
            + ("rest detection kept none of their rows (see its report; --rest all fits "
               "every row)" if any(r.rest is not None for r in runs) else "they are empty"))
    return np.asarray(t, dtype=np.float64), np.asarray(d, dtype=np.float64)


def _range(runs: Sequence[RunFeatures]) -> ValidRange:
    t, d = _extremes(runs)
    return ValidRange(float(t.min()), float(t.max()), float(d.min()), float(d.max()))


def default_scaling(runs: Sequence[RunFeatures]) -> Scaling:
    """:meth:`Scaling.from_data` of all runs' rows (the same from their extremes)."""
    return Scaling.from_data(*_extremes(runs))


def fit(
    runs: Sequence[RunFeatures],
    model: ModelSpec | str,
    *,
    estimator: EstimatorConfig,
    method: Method = "pooled",
    scaling: Scaling | None = None,
) -> Calibration:
    """Fit ``model`` to ``runs`` (features made with ``estimator``)."""
    spec = get_model(model) if isinstance(model, str) else model
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; known: {', '.join(METHODS)}")
    axes = common_axes(runs)
    scaling = scaling or default_scaling(runs)
    coefficients: dict[str, tuple[float, ...]] = {}
    for axis in axes:
        if method == "offsets":
            c, _ = solve_offsets(spec, scaling, runs, axis)
        elif method == "pooled":
            c = _solve(spec, scaling, runs, axis)
        else:
            c = mean_coefficients([_solve(spec, scaling, [r], axis) for r in runs])
        coefficients[axis] = tuple(float(v) for v in c)
    calibration = Calibration(
        model=spec,
        scaling=scaling,
        coefficients=coefficients,
        valid_range=_range(runs),
        estimator=estimator,
        provenance={
            "method": method,
            "runs": [{"name": r.name, "source": r.source, "sha256": r.sha256,
                      "rows": len(r.time_s),
                      **({} if r.rest is None else {"rest_rows": int(np.sum(r.rest))})}
                     for r in runs],
            "fit_time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "gyrotherm_version": __version__,
        },
    )
    metrics = {s.axis + ":" + s.run: s.compensated.to_dict()
               for r in runs for s in score(calibration, r)}
    return replace(calibration, provenance={**calibration.provenance, "residuals": metrics})


def fit_per_run(
    runs: Sequence[RunFeatures],
    model: ModelSpec | str,
    *,
    estimator: EstimatorConfig,
    scaling: Scaling | None = None,
) -> list[Calibration]:
    """One fit per run, all with the same scaling (Table 1)."""
    scaling = scaling or default_scaling(runs)
    return [fit([r], model, estimator=estimator, method="pooled", scaling=scaling) for r in runs]


@dataclass(frozen=True)
class RemovedBias:
    """:func:`removed_bias`' result."""

    bias: Mapping[str, tuple[FloatArray, NDArray[np.bool_]]]
    """Per calibration axis: bias removed on each row (°/s), rows with T or ΔT clamped."""
    zero: ZeroSeries | None
    """The boot-time zero (None without one); included in ``bias``."""


def removed_bias(calibration: Calibration, run: RunFeatures, *,
                 zero: ZeroConfig | None = None) -> RemovedBias:
    """Per calibration axis of ``run``: the bias the daemon removes on each row (°/s)
    and the rows where T or ΔT was clamped.

    Effects (version 2) are evaluated online from the run's first row (their
    runtime state starts at power-on there; t_on = the run's time column). With
    ``zero`` the boot-time zero is measured as the daemon measures it
    (:func:`~gyrotherm.compensation._zero.zero_series` on ω − b of every rate axis
    of the run, 0 bias on an axis the calibration lacks) and added from its
    accepting row on."""
    out = {axis: calibration.bias_series(axis, run.temperature_c, run.delta_t_c, run.time_s)
           for axis in calibration.axes if axis in run.rates_dps}
    if zero is None:
        return RemovedBias(out, None)
    residual = {a: run.rates_dps[a] - out[a][0] if a in out else run.rates_dps[a]
                for a in run.rates_dps}
    zs = zero_series(zero, run.time_s, residual)
    return RemovedBias({a: (b + zs.offset_dps[a], c) for a, (b, c) in out.items()}, zs)


def score(calibration: Calibration, run: RunFeatures, *, zero: ZeroConfig | None = None,
          removed: RemovedBias | None = None) -> list[RunScore]:
    """Raw and compensated error metrics of ``run`` under ``calibration``, per axis,
    with the bias of :func:`removed_bias` (effects from the run's first row; the
    boot-time zero with ``zero``). With a ``rest`` mask only the rest rows are
    scored (the bias is evaluated on every row). ``truth`` compares with the run's
    true bias, which excludes the switch-on offset a zero removes. ``removed``: the
    result of :func:`removed_bias` when the caller has it already (``zero`` unused)."""
    out = []
    rb = removed if removed is not None else removed_bias(calibration, run, zero=zero)
    for axis, (bias, clamped) in rb.bias.items():
        bias, clamped = run.rows(bias), run.rows(clamped)
        raw = run.rows(run.rates_dps[axis])
        truth = run.true_bias_dps.get(axis)
        truth = None if truth is None else run.rows(truth)
        out.append(RunScore(
            run=run.name,
            axis=axis,
            raw=ErrorMetrics.of(raw),
            compensated=ErrorMetrics.of(raw - bias),
            truth=None if truth is None else ErrorMetrics.of(bias - truth),
            clamped_fraction=float(np.mean(clamped)) if clamped.size else float("nan"),
        ))
    return out


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-run-out result: fitted on all runs but ``run``, scored on ``run``."""

    run: str
    scores: tuple[RunScore, ...]


def leave_one_out(
    runs: Sequence[RunFeatures],
    model: ModelSpec | str,
    *,
    estimator: EstimatorConfig,
    method: Method = "pooled",
    progress: Callable[[int, int], None] | None = None,
) -> list[HeldOut]:
    """Fit on every run but one and score the one left out, for every run."""
    if len(runs) < 2:
        raise CalibrationError("leave-one-run-out needs at least 2 runs")
    scaling = default_scaling(runs)
    out = []
    for i, held in enumerate(runs):
        rest = [r for j, r in enumerate(runs) if j != i]
        cal = fit(rest, model, estimator=estimator, method=method, scaling=scaling)
        out.append(HeldOut(held.name, tuple(score(cal, held))))
        if progress:
            progress(i + 1, len(runs))
    return out
