"""Where an unexplained structure is: all of it, not only its steepest part.

The correction of an unexplained structure (:mod:`._unexplained`) is a linear spline
c(v) on K knots k_0 < … < k_{K−1} over the runs' 0.5–99.5 % range of its variable v,
fitted (two-stage) to the final catalogued model's residuals with one offset per run.
Its level is arbitrary (the offsets hold it), so where the structure *is* means where
c changes. Single knot intervals are too noisy to test one by one (with Gauss–Markov
bias noise τ_int is hundreds of 1-s blocks: a ×4 held-out gain can have no interval
beyond 2.5 standard errors), so c is cut into its monotone runs [k_i, k_j] (maximal, a
flat interval joining the run before it), and the noise's wiggles are smoothed over
(:func:`significant_runs`): while the least significant run, one in which no change
c(k_b) − c(k_a) its way (i ≤ a < b ≤ j) reaches :data:`Z_CHANGE` · SE, lies between
two others it joins them (they move the same way: a wiggle on a slope is not a turn; a
V of |ΔT| is two runs, not seven), and at an end it is dropped. SE comes from the
covariance of the spline values, σ²·τ_int·(BᵀB)⁺ (B the hats, centred per run; σ² the
residual variance after the spline; τ_int the residuals' integrated autocorrelation
time in blocks, as in the selection's n_eff; pseudo-inverse: the constant is not
identified, its differences are). Every run left is significant, and every one is part
of the structure, however gentle: until round 13 a run also had to be ≥ ¼ as steep as
the steepest, which cut off what a saturating response asks of the correction beyond
the knee (the catalogued ΔT terms tilt the saturated sides, and the correction takes
the tilt back: that is structure the model lacks) and one side of a noisy |ΔT|. Each
run's end intervals flatter than :data:`REL_SLOPE` of its own steepest are trimmed (a
step's flat sides join it otherwise).

``where`` = [first, last] over those runs (a periodic bias: every half-period),
widened by :data:`PAD_INTERVALS` knot interval on each side within the data's
range (a hat is two intervals wide: the spline places a boundary no finer; a
step's tails, a peak in the last interval). It is where the correction changes
the catalogued model's prediction: the paper's T, T² (and ΔT) terms take part
of a structure (a bias step's best quadratic), so what the correction adds on
top spans more than the structure's steep part — a step's ``where`` brackets
the step and may reach far beyond it. Outside ``where`` the correction's change is
within the noise: the data cannot place the structure there, nor rule it out (the
report says so when ``where`` is short of the data's range).
The steep part alone (the knot intervals contiguous with the steepest one and
at least half as steep, :func:`~._unexplained.steepest_span`) is
``Unexplained.steepest``: how sharp the structure is, and where a step is;
:mod:`._resolution` compares it with the readout.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._score import integrated_time

FloatArray = NDArray[np.float64]

Z_CHANGE = 3.0
"""A monotone run is part of the structure when its change is this many standard errors
from zero; a smaller reversal between two runs is a wiggle and joins them."""
REL_SLOPE = 0.25
"""A run's end intervals flatter than this share of its steepest interval are trimmed."""
PAD_INTERVALS = 1
"""Knot intervals added on each side: a hat is two intervals wide, so the spline places a
boundary no finer than one (a step's tails, a peak in the last interval)."""


def values_with_covariance(
    blocks: Sequence[FloatArray], residuals: Sequence[FloatArray], knots: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Spline values at the knots (zero mean over the blocks) and their covariance
    σ²·τ_int·(BᵀB)⁺, from per-run hat matrices ``blocks`` (n_r × K) and residuals."""
    b = np.vstack([h - h.mean(axis=0, keepdims=True) for h in blocks])
    e = np.concatenate([r - r.mean() for r in residuals])
    beta, *_ = np.linalg.lstsq(b, e, rcond=1e-10)
    left = e - b @ beta
    sigma2 = float(left @ left) / max(len(e) - len(knots), 1)
    bounds = np.cumsum([len(h) for h in blocks])[:-1]
    tau = integrated_time(np.split(left, bounds))
    cov = sigma2 * tau * np.linalg.pinv(b.T @ b, rcond=1e-10)
    fitted = np.vstack(list(blocks)) @ beta
    return np.asarray(beta - fitted.mean(), dtype=np.float64), np.asarray(cov, dtype=np.float64)


def segments(values: FloatArray) -> list[tuple[int, int]]:
    """Maximal runs of knot intervals over which ``values`` move one way, as (first
    knot, last knot); a flat interval joins the run before it."""
    sign = np.sign(np.diff(values))
    out: list[tuple[int, int]] = []
    start, current = 0, 0.0
    for i, s in enumerate(sign.tolist()):
        if s != 0 and current != 0 and s != current:
            out.append((start, i))
            start = i
        if s != 0:
            current = s
    out.append((start, len(values) - 1))
    return out


def _core(knots: FloatArray, values: FloatArray, i: int, j: int) -> tuple[int, int]:
    """Knots [i, j] of a monotone run without its end intervals flatter than
    :data:`REL_SLOPE` of its steepest (a step's flat sides join it otherwise)."""
    slope = np.abs(np.diff(values[i:j + 1]) / np.diff(knots[i:j + 1]))
    strong = np.flatnonzero(slope >= REL_SLOPE * float(slope.max()))
    return i + int(strong[0]), i + int(strong[-1]) + 1


def _pair_z(values: FloatArray, cov: FloatArray) -> FloatArray:
    """z[a, b] = (c(k_b) − c(k_a)) / SE, SE² = cov[a, a] + cov[b, b] − 2·cov[a, b]."""
    var = np.diag(cov)[:, None] + np.diag(cov)[None, :] - 2.0 * cov
    diff = values[None, :] - values[:, None]
    return np.asarray(diff / np.sqrt(np.maximum(var, 1e-300)), dtype=np.float64)


def _z(z: FloatArray, values: FloatArray, i: int, j: int) -> float:
    """The largest change of a run [i, j] in its own direction between any two of its
    knots, in standard errors (``z`` from :func:`_pair_z`): the run changes significantly
    when some part of it does (a longer span can carry a noisier end knot)."""
    way = 1.0 if values[j] >= values[i] else -1.0
    return max(0.0, float(np.max(np.triu(way * z[i:j + 1, i:j + 1], 1))))


def significant_runs(values: FloatArray, cov: FloatArray) -> list[tuple[int, int]]:
    """The monotone runs of ``values`` once reversals within the noise are smoothed over:
    while the least significant run (no change within it of :data:`Z_CHANGE` · SE its
    way, :func:`_z`) is inside, it joins its two neighbours (which move the same way: a
    wiggle on a slope is not a turn); at an end it is dropped. What is left is
    significant, or one run."""
    return _smoothed(_pair_z(values, cov), values)


def _smoothed(z: FloatArray, values: FloatArray) -> list[tuple[int, int]]:
    runs = segments(values)
    while len(runs) > 1:
        score = [_z(z, values, i, j) for i, j in runs]
        n = int(np.argmin(score))
        if score[n] >= Z_CHANGE:
            break
        if n == 0 or n == len(runs) - 1:
            runs.pop(n)
        else:
            runs[n - 1:n + 2] = [(runs[n - 1][0], runs[n + 1][1])]
    return runs


def support_span(knots: FloatArray, values: FloatArray, cov: FloatArray) -> tuple[float, float]:
    """[low, high] over the significant monotone runs (:func:`significant_runs`; module
    docstring), the steepest monotone run alone when none is significant."""
    z = _pair_z(values, cov)
    runs = _smoothed(z, values)
    if _z(z, values, *runs[0]) < Z_CHANGE:  # one run left, and not significant
        cores = [_core(knots, values, i, j) for i, j in segments(values)]
        runs = [max(cores, key=lambda r: abs(values[r[1]] - values[r[0]])
                    / (knots[r[1]] - knots[r[0]]))]
    chosen = [_core(knots, values, i, j) for i, j in runs]
    first = max(chosen[0][0] - PAD_INTERVALS, 0)
    last = min(chosen[-1][1] + PAD_INTERVALS, len(knots) - 1)
    return float(knots[first]), float(knots[last])
