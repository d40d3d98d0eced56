"""Rest detection's building blocks: the run cut at logging gaps into pieces, each piece
into blocks, per-block statistics, robust z-scores, the running median of the rest level
and the level-change test (:mod:`gyrotherm.compensation._rest` puts them together)."""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from gyrotherm.compensation._rest import RestConfig

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IndexArray = NDArray[np.intp]
MAD_TO_SIGMA = 1.4826  # 1.4826·MAD → σ for a Gaussian


def gap_threshold_s(dt_s: float, config: RestConfig) -> float:
    """A step between two rows longer than this is a logging gap: ``gap_s``, or
    ``gap_median_factor`` median row periods when that is longer (a 1-Hz log's rows
    are 1 s apart, none of them a gap)."""
    return max(config.gap_s, config.gap_median_factor * dt_s)


def piece_starts(time_s: FloatArray, dt_s: float, config: RestConfig) -> IndexArray:
    """First row of each piece: the run is cut after every logging gap."""
    gaps = np.flatnonzero(np.diff(time_s) > gap_threshold_s(dt_s, config)) + 1
    return np.concatenate(([0], gaps)).astype(np.intp)


def blocks(n: int, pieces: IndexArray, dt_s: float, config: RestConfig) -> IndexArray:
    """Start rows of the blocks of ``window_s`` (at least ``min_rows`` rows), inside each
    piece (no block spans a gap); a piece's tail shorter than half a block joins its last
    block; a piece shorter than a block is one block."""
    rows = max(config.min_rows, round(config.window_s / dt_s) if dt_s > 0 else config.min_rows)
    out = []
    for a, b in zip(pieces, np.append(pieces[1:], n), strict=True):
        starts = np.arange(a, b, rows, dtype=np.intp)
        if len(starts) > 1 and b - starts[-1] < rows / 2:
            starts = starts[:-1]
        out.append(starts)
    return np.concatenate(out).astype(np.intp)


def block_stats(x: FloatArray, starts: IndexArray) -> tuple[FloatArray, FloatArray]:
    """Mean and (population) variance of ``x`` per block."""
    x = x - np.median(x)  # centred: sums of squares without cancellation
    counts = np.diff(np.append(starts, len(x))).astype(np.float64)
    mean = np.add.reduceat(x, starts) / counts
    var = np.maximum(np.add.reduceat(x * x, starts) / counts - mean * mean, 0.0)
    return mean, var


def block_any(flags: BoolArray, starts: IndexArray) -> BoolArray:
    """Per block: is any of its rows flagged."""
    out: BoolArray = np.add.reduceat(flags.astype(np.intp), starts) > 0
    return out


def robust_z(f: FloatArray, at_rest: BoolArray, floor: float) -> FloatArray:
    """(f − median)/(1.4826·MAD), both over the rest blocks; the scale is at least ``floor``."""
    ref = f[at_rest] if np.any(at_rest) else f
    m = float(np.median(ref))
    s = max(MAD_TO_SIGMA * float(np.median(np.abs(ref - m))), floor)
    return (f - m) / s


def running_median(mean: FloatArray, at_rest: BoolArray, half: int) -> FloatArray:
    """Median of the rest blocks' means within ± ``half`` blocks (global median if none).

    The window stays centred: the first and last ``half`` blocks use ± min(i, n−1−i)
    blocks, so that a bias drifting linearly (a fast thermal ramp at power-on) leaves
    no offset at the ends of the log, where a one-sided window would lag the drift by
    slope × half a window."""
    vals = np.where(at_rest, mean, np.nan)
    padded = np.pad(vals, half, constant_values=np.nan)
    view = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-nan windows
        med = np.nanmedian(view, axis=1)
        n = len(vals)
        for i in (*range(min(half, n)), *range(max(half, n - half), n)):
            h = min(i, n - 1 - i)
            med[i] = np.nanmedian(vals[i - h:i + h + 1])
    fallback = float(np.median(mean[at_rest])) if np.any(at_rest) else float(np.median(mean))
    return np.where(np.isfinite(med), med, fallback)


def rows_of(block_flags: BoolArray, starts: IndexArray, n: int) -> BoolArray:
    return np.repeat(block_flags, np.diff(np.append(starts, n)))


def spans(flags: BoolArray, breaks: IndexArray | None = None) -> list[tuple[int, int]]:
    """[start, stop) index spans where ``flags`` is True; a span is also cut at each
    index of ``breaks`` (the first row or block after a logging gap)."""
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    out: list[tuple[int, int]] = []
    cut_at = np.zeros(0, dtype=np.intp) if breaks is None else np.sort(breaks)
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        inside = cut_at[np.searchsorted(cut_at, a, side="right"):np.searchsorted(cut_at, b)]
        bounds = [int(a), *(int(c) for c in inside), int(b)]
        out.extend(itertools.pairwise(bounds))
    return out


def level_changes(stats: Mapping[str, tuple[FloatArray, FloatArray]], at_rest: BoolArray,
                  half: int, config: RestConfig, breaks: IndexArray) -> BoolArray:
    """Rest stretches that are plateaus: a constant-rate turn longer than the running
    median (no variance, no offset against its own median) between two rest stretches.

    Across the gaps before and after a stretch, the level jumps j_in = (its first ≤ K
    block means) − (the previous stretch's last K) and j_out = (the next stretch's first
    K) − (its last K), medians, K = ``half``. A stretch is flagged when, on some axis,
    both jumps exceed max(threshold·σ_step, ``min_rate_dps``) with opposite signs (up,
    then back down). Thermal drift moves the level one way across both gaps and passes.
    A turn at either end of the log has one neighbour only and is not judged here.
    Stretches are cut at logging gaps (``breaks``, block indices)."""
    found = spans(at_rest, breaks)
    out = np.zeros(len(at_rest), dtype=bool)
    for mean, _ in stats.values():
        step = np.diff(mean[at_rest]) if at_rest.sum() > 2 else np.diff(mean)
        tol = max(config.threshold * MAD_TO_SIGMA / np.sqrt(2.0)
                  * float(np.median(np.abs(step))) if len(step) else 0.0,
                  config.min_rate_dps)
        first = [float(np.median(mean[a:min(b, a + half)])) for a, b in found]
        last = [float(np.median(mean[max(a, b - half):b])) for a, b in found]
        for i in range(1, len(found) - 1):
            j_in, j_out = first[i] - last[i - 1], first[i + 1] - last[i]
            if min(abs(j_in), abs(j_out)) > tol and j_in * j_out < 0:
                a, b = found[i]
                out[a:b] = True
    return out


def physical_rows(rates_dps: Mapping[str, FloatArray], armed: FloatArray | None,
                  config: RestConfig) -> dict[str, BoolArray]:
    """Row flags of the row-level physical limits, by reason: the rate magnitude above
    ``max_rate_dps``; the vehicle armed."""
    names = config.physical_reasons()
    mag = np.sqrt(sum(np.asarray(v, dtype=np.float64) ** 2 for v in rates_dps.values()))
    out = {names["rate"]: np.asarray(mag > config.max_rate_dps)}
    if armed is not None:
        out[names["armed"]] = np.asarray(armed, dtype=np.float64) > 0.5
    return out


def min_segment(t: FloatArray, pieces: IndexArray, dt_s: float, config: RestConfig
                ) -> tuple[float, float]:
    """The minimum rest stretch for this log and the time its rows cover (each piece
    between gaps from its first row to one period past its last), s."""
    ends = np.append(pieces[1:], len(t)) - 1
    covered = float(np.sum(t[ends] - t[pieces])) + len(pieces) * dt_s
    return min(config.min_segment_s, config.min_segment_fraction * covered), covered


def statistical_reasons(stats: Mapping[str, tuple[FloatArray, FloatArray]],
                        acc_var: FloatArray | None, at_rest: BoolArray, half: int,
                        config: RestConfig) -> dict[str, BoolArray]:
    """One pass of the statistical tests on the blocks, scored against ``at_rest``."""
    nb = len(at_rest)
    out = {"rate variance": np.zeros(nb, bool), "rate offset": np.zeros(nb, bool)}
    for mean, var in stats.values():
        z_var = robust_z(np.log(var + 1e-30), at_rest, 0.05)
        out["rate variance"] |= (z_var > config.threshold) & (var > config.min_rate_dps**2)
        high = mean - running_median(mean, at_rest, half)
        z_off = np.abs(robust_z(high, at_rest, 1e-12))
        out["rate offset"] |= (z_off > config.threshold) & (np.abs(high) > config.min_rate_dps)
        step = np.diff(mean, prepend=mean[0])  # a level change between two blocks
        z_step = np.abs(robust_z(step, at_rest, 1e-12))
        out["rate offset"] |= (z_step > config.threshold) & (np.abs(step) > config.min_rate_dps)
    if acc_var is not None:
        out["accel variance"] = robust_z(np.log(acc_var + 1e-30), at_rest,
                                         0.05) > config.threshold
    return out
