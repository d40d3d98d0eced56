"""The ``offsets`` fit: pooled least squares with one switch-on offset per run, on 1-s
blocks — what ``gyrotherm fit`` does by default and what ``gyrotherm diagnose
--calibration`` fits (:mod:`gyrotherm.analysis._score`), so the two give the same paper
calibration from the same data (tests/cli/test_fit_matches_diagnose.py).

Per run r, the rows (its rest rows, when it has a rest mask) are averaged over 1-s
blocks of time since the run's first row: T̄_b, ΔT̄_b, ȳ_b (unweighted blocks: a 1 kHz
and a 10 Hz run cost the same, and white noise above 0.5 Hz carries no bias
information). With A_r the model's terms at (T̄, ΔT̄) without the constant column,

    min over c, o_r of  Σ_r Σ_b (ȳ_rb − A_rb c − o_r)²

is, by Frisch–Waugh, the least squares of the per-run centred rates on the per-run
centred terms (ỹ = ȳ − mean_r ȳ, Ã = A − mean_r A; blockwise QR of the stacked
``[Ã | ỹ]``, as :func:`gyrotherm.compensation._fit._solve`), then
o_r = mean_r ȳ − (mean_r A) c. A switch-on offset differs from run to run and no model
in T or ΔT predicts it: with one intercept for every run (``pooled``), runs at different
temperatures pass their offsets into the T terms. The calibration's constant term is
the mean of the o_r (the offset a new run is expected to have; the boot-time zero
measures the actual one).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._models import ModelSpec, Scaling

if TYPE_CHECKING:
    from gyrotherm.compensation._fit import RunFeatures

FloatArray = NDArray[np.float64]
BLOCK_S = 1.0
"""Block length, s (the diagnosis' 1-s blocks: :mod:`gyrotherm.analysis._prep` uses these)."""


def blocks(time_s: FloatArray, keep: NDArray[np.bool_] | None = None
           ) -> tuple[NDArray[np.int64], FloatArray]:
    """Per row (of the rows ``keep`` selects), the index of its 1-s block of time since
    the first row, and each block's row count (blocks without a row dropped)."""
    idx = np.floor((time_s - time_s[0]) / BLOCK_S).astype(np.int64)
    if keep is not None:
        idx = idx[keep]
    _, inverse, counts = np.unique(idx, return_inverse=True, return_counts=True)
    return inverse, counts.astype(np.float64)


def block_mean(values: FloatArray, inverse: NDArray[np.int64], counts: FloatArray
               ) -> FloatArray:
    """``values`` (one per row of :func:`blocks`) averaged per block."""
    return np.bincount(inverse, weights=values, minlength=len(counts)) / counts


def block_means(run: RunFeatures, axis: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """T, ΔT and the ``axis`` rate of ``run`` averaged over 1-s blocks of time since its
    first row (rest rows only, when it has a rest mask; blocks without one dropped)."""
    inverse, counts = blocks(run.time_s, run.rest)
    t, d, y = (run.rows(v) for v in (run.temperature_c, run.delta_t_c, run.rates_dps[axis]))
    return (block_mean(t, inverse, counts), block_mean(d, inverse, counts),
            block_mean(y, inverse, counts))


def solve_triangular_checked(r: FloatArray, k: int, n: int,
                             why: Callable[[int], str]) -> FloatArray:
    """The k coefficients from the triangular factor ``r`` of ``[A | y]`` (n rows; the last
    column of ``r`` is Qᵀy): ``R[:k, :k] c = Qᵀy[:k]``. Rank: the singular values of
    ``R[:k, :k]`` (those of A) against ``lstsq``'s default cut ``max(n, k)·ε·σ_max``; below
    k, :class:`CalibrationError` with ``why(rank)``."""
    rk = r[:k, :k]
    sv = np.linalg.svd(rk, compute_uv=False) if rk.shape[0] == k else np.zeros(k)
    rank = int(np.sum(sv > max(n, k) * np.finfo(np.float64).eps * (sv[0] if len(sv) else 0)))
    if rank < k:
        raise CalibrationError(why(rank))
    return np.asarray(np.linalg.solve(rk, r[:k, k]), dtype=np.float64)


def solve_offsets(spec: ModelSpec, scaling: Scaling, runs: Sequence[RunFeatures],
                  axis: str) -> tuple[FloatArray, FloatArray]:
    """The model's coefficients (the constant term = the mean per-run offset) and the
    per-run offsets o_r, °/s (module docstring)."""
    if "1" not in spec.term_names:
        raise CalibrationError(f"method 'offsets' needs a constant term; model "
                               f"{spec.name!r} has {list(spec.term_names)}")
    const = spec.term_names.index("1")
    k = len(spec.terms) - 1
    r = np.zeros((0, k + 1))
    n = 0
    means: list[tuple[FloatArray, float]] = []
    for run in runs:
        t, d, y = block_means(run, axis)
        if len(y) == 0:
            raise CalibrationError(f"{run.source}: run {run.name!r} has no rows to fit "
                                   f"(axis {axis})")
        a = np.delete(spec.design(*scaling.centre(t, d)), const, axis=1)
        a_mean, y_mean = a.mean(axis=0), float(y.mean())
        means.append((a_mean, y_mean))
        block = np.column_stack([a - a_mean, y - y_mean])
        r = cast(FloatArray, np.linalg.qr(np.vstack([r, block]), mode="r"))
        n += len(block)
    if n - len(runs) < 2 * k:
        raise CalibrationError(f"model {spec.name!r} with one offset per run needs at least "
                               f"{2 * k} 1-s blocks beyond one per run, got {n - len(runs)}")
    c = solve_triangular_checked(
        r, k, n, lambda rank: (
            f"model {spec.name!r} is not identifiable from runs {[x.name for x in runs]} "
            f"with one offset per run: design rank {rank} < {k} terms (e.g. no temperature "
            "change within a run, or no ΔT variation for a ΔT model)"))
    offsets = np.array([y_mean - float(a_mean @ c) for a_mean, y_mean in means])
    return np.insert(c, const, float(offsets.mean())), offsets


#: :func:`choose_method` picks ``offsets`` from this within-run share of T's variance up.
WITHIN_SHARE_MIN = 0.5


def within_run_share(runs: Sequence[RunFeatures]) -> float:
    """The share of the 1-s block temperatures' variance that lies within runs,
    Σ_r Σ_b (T̄_rb − mean_r)² / Σ_r Σ_b (T̄_rb − mean)², in [0, 1] (1 for one run; 0 when
    T never changes): what is left for the T terms once each run has its own offset."""
    temps = [block_means(r, next(iter(r.rates_dps)))[0] for r in runs]
    temps = [t for t in temps if len(t)]
    if not temps:
        return 0.0
    allt = np.concatenate(temps)
    total = float(np.sum((allt - allt.mean()) ** 2))
    within = float(sum(np.sum((t - t.mean()) ** 2) for t in temps))
    return within / total if total > 0.0 else 0.0


def choose_method(runs: Sequence[RunFeatures]) -> tuple[str, float]:
    """``offsets`` when the runs' own temperature changes carry at least
    :data:`WITHIN_SHARE_MIN` of T's variance (warm-ups, chamber ramps: each run spans
    temperature), else ``pooled`` (isothermal plateaus, one per run: the T terms can only
    come from the levels between runs, which per-run offsets would absorb); and the share."""
    share = within_run_share(runs)
    return ("offsets" if share >= WITHIN_SHARE_MIN else "pooled"), share
