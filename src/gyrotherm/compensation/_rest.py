"""Rest detection: which rows of a log show the gyro at rest, so that only those feed a fit.

A bias fit needs the true rate to be zero; a log with motion (a flight, a hand-held
turn, a vehicle driven about) must have its moving rows left out. They are *masked*,
not cut: ΔT = τ·dT/dt is estimated over the whole run (the estimator needs the
temperature history through the motion), and the fit then skips the masked rows
(:class:`gyrotherm.compensation.RunFeatures` ``rest``).

Features, on consecutive blocks b of ``window_s`` seconds (n_b ≥ ``min_rows`` rows),
per rate axis a (°/s) and, when the run has one, the accelerometer (m/s²):

* rate variance  v_ab = (1/n_b) Σ (ω_i − ω̄_ab)², tested as ln v_ab;
* high-pass rate h_ab = ω̄_ab − median_{|b'−b| ≤ K} ω̄_ab', tested as |z|, the block mean minus a
  running median over ± ``baseline_s`` of rest blocks (a constant-rate turn has no
  variance but an offset; the slow thermal drift of the bias passes the median);
* rate steps  s_ab = ω̄_ab − ω̄_a(b−1) (a level change, even on a block boundary);
* accelerometer magnitude variance  ln var_b(|a|), |a| = √(a_x² + a_y² + a_z²);
* rate level of whole rest stretches against their neighbours' (a constant-rate turn
  longer than the running median has neither variance nor offset inside).

Each feature f is scored against the gyro's own noise, robustly: z_b = (f_b − m)/s with
m = median and s = 1.4826·MAD of f over the blocks judged at rest (two passes: all
blocks, then the rest blocks of the first pass). A block is in motion when any z_b
exceeds ``threshold``, and, for the rate features, the rate deviation also exceeds
``min_rate_dps`` (so that a noise-free simulated gyro is not declared moving by its own
rounding). For ln v of n Gaussian samples the spread is ≈ √(2/(n−1)), so the
threshold adapts to the rows per block. Motion blocks are widened by ``guard_s`` on
each side, and rest stretches shorter than ``min_segment_s`` are excluded too.

Assumption: most of the log is at rest (medians over all blocks start the first pass).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
ACCEL_KEYS = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
"""``Run.extra`` columns of the accelerometer, m/s² (written by gyrotherm.readers)."""
_MAD = 1.4826  # MAD → σ for a Gaussian


@dataclass(frozen=True)
class RestConfig:
    """Rest-detection settings (units in the names; see the module docstring)."""

    window_s: float = 1.0
    min_rows: int = 5
    threshold: float = 6.0
    baseline_s: float = 20.0
    guard_s: float = 1.0
    min_segment_s: float = 30.0
    min_rate_dps: float = 0.05

    def __post_init__(self) -> None:
        for name in ("window_s", "threshold", "baseline_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"rest.{name} must be a positive number, got {v!r}")
        for name in ("guard_s", "min_segment_s", "min_rate_dps"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ConfigError(f"rest.{name} must be a number >= 0, got {v!r}")
        if self.min_rows < 2:
            raise ConfigError(f"rest.min_rows must be >= 2, got {self.min_rows!r}")


@dataclass(frozen=True)
class ExcludedSegment:
    """Rows [start_s, end_s] (s, the run's time column) left out, and why."""

    start_s: float
    end_s: float
    reasons: tuple[str, ...]

    def to_dict(self) -> dict[str, object]:
        return {"start_s": self.start_s, "end_s": self.end_s, "reasons": list(self.reasons)}


@dataclass(frozen=True)
class RestReport:
    """What rest detection kept and left out of one run."""

    run: str
    rest: BoolArray = field(repr=False)
    """Row mask, True = at rest (fed to the fit)."""
    segments: tuple[ExcludedSegment, ...]
    excluded_s: float
    total_s: float
    noise_dps: Mapping[str, float]
    """Per axis: the robust rate noise σ at rest, √(median v_ab), °/s."""
    note: str = ""
    """Why detection did not run (too few rows), when it did not."""

    @property
    def excluded_fraction(self) -> float:
        return float(1.0 - np.mean(self.rest)) if len(self.rest) else 0.0

    def to_dict(self) -> dict[str, object]:
        return {"run": self.run, "rows": len(self.rest),
                "excluded_rows": int(np.count_nonzero(~self.rest)),
                "excluded_s": self.excluded_s, "total_s": self.total_s,
                "excluded_fraction": self.excluded_fraction,
                "noise_dps": dict(self.noise_dps),
                "segments": [s.to_dict() for s in self.segments],
                **({"note": self.note} if self.note else {})}


def _blocks(time_s: FloatArray, config: RestConfig) -> NDArray[np.intp]:
    """Start rows of the blocks; the tail shorter than half a block joins the last one."""
    n = len(time_s)
    dt = float(np.median(np.diff(time_s))) if n > 1 else 1.0
    rows = max(config.min_rows, round(config.window_s / dt) if dt > 0 else config.min_rows)
    starts = np.arange(0, n, rows, dtype=np.intp)
    if len(starts) > 1 and n - starts[-1] < rows / 2:
        starts = starts[:-1]
    return starts


def _block_stats(x: FloatArray, starts: NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
    """Mean and (population) variance of ``x`` per block."""
    x = x - np.median(x)  # centred: sums of squares without cancellation
    counts = np.diff(np.append(starts, len(x))).astype(np.float64)
    mean = np.add.reduceat(x, starts) / counts
    var = np.maximum(np.add.reduceat(x * x, starts) / counts - mean * mean, 0.0)
    return mean, var


def _robust_z(f: FloatArray, at_rest: BoolArray, floor: float) -> FloatArray:
    """(f − median)/(1.4826·MAD), both over the rest blocks; the scale is at least ``floor``."""
    ref = f[at_rest] if np.any(at_rest) else f
    m = float(np.median(ref))
    s = max(_MAD * float(np.median(np.abs(ref - m))), floor)
    return (f - m) / s


def _running_median(mean: FloatArray, at_rest: BoolArray, half: int) -> FloatArray:
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


def _rows_of(block_flags: BoolArray, starts: NDArray[np.intp], n: int) -> BoolArray:
    return np.repeat(block_flags, np.diff(np.append(starts, n)))


def _spans(flags: BoolArray) -> list[tuple[int, int]]:
    """[start, stop) index spans where ``flags`` is True."""
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _level_changes(stats: Mapping[str, tuple[FloatArray, FloatArray]], at_rest: BoolArray,
                   half: int, config: RestConfig) -> BoolArray:
    """Rest stretches that are plateaus: a constant-rate turn longer than the running
    median (no variance, no offset against its own median) between two rest stretches.

    Across the gaps before and after a stretch, the level jumps j_in = (its first ≤ K
    block means) − (the previous stretch's last K) and j_out = (the next stretch's first
    K) − (its last K), medians, K = ``half``. A stretch is flagged when, on some axis,
    both jumps exceed max(threshold·σ_step, ``min_rate_dps``) with opposite signs (up,
    then back down). Thermal drift moves the level one way across both gaps and passes.
    A turn at either end of the log has one neighbour only and is not judged here."""
    spans = _spans(at_rest)
    out = np.zeros(len(at_rest), dtype=bool)
    for mean, _ in stats.values():
        step = np.diff(mean[at_rest]) if at_rest.sum() > 2 else np.diff(mean)
        tol = max(config.threshold * _MAD / np.sqrt(2.0) * float(np.median(np.abs(step))),
                  config.min_rate_dps)
        first = [float(np.median(mean[a:min(b, a + half)])) for a, b in spans]
        last = [float(np.median(mean[max(a, b - half):b])) for a, b in spans]
        for i in range(1, len(spans) - 1):
            j_in, j_out = first[i] - last[i - 1], first[i + 1] - last[i]
            if min(abs(j_in), abs(j_out)) > tol and j_in * j_out < 0:
                a, b = spans[i]
                out[a:b] = True
    return out


def detect_rest(
    time_s: FloatArray,
    rates_dps: Mapping[str, FloatArray],
    *,
    accel_mps2: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    config: RestConfig | None = None,
    name: str = "",
) -> RestReport:
    """Rest mask of a run's rows from its rates (°/s) and, optionally, its accelerometer."""
    config = config or RestConfig()
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    if n < 2 * config.min_rows:
        raise ConfigError(f"run {name!r}: {n} rows are too few for rest detection "
                          f"(at least {2 * config.min_rows}); use --rest all")
    starts = _blocks(t, config)
    nb = len(starts)
    dt = float(np.median(np.diff(t)))
    block_s = float(starts[1] - starts[0]) * dt if nb > 1 else config.window_s
    half = max(1, round(config.baseline_s / block_s))
    stats = {a: _block_stats(np.asarray(v, dtype=np.float64), starts)
             for a, v in rates_dps.items()}
    acc_var = None
    if accel_mps2 is not None:
        mag = np.sqrt(sum(np.asarray(c, dtype=np.float64) ** 2 for c in accel_mps2))
        acc_var = _block_stats(mag, starts)[1]
    at_rest = np.ones(nb, dtype=bool)
    reasons: dict[str, BoolArray] = {}
    for _ in range(2):
        reasons = {"rate variance": np.zeros(nb, bool), "rate offset": np.zeros(nb, bool)}
        for mean, var in stats.values():
            z_var = _robust_z(np.log(var + 1e-30), at_rest, 0.05)
            reasons["rate variance"] |= (z_var > config.threshold) & (
                var > config.min_rate_dps**2)
            high = mean - _running_median(mean, at_rest, half)
            z_off = np.abs(_robust_z(high, at_rest, 1e-12))
            reasons["rate offset"] |= (z_off > config.threshold) & (
                np.abs(high) > config.min_rate_dps)
            step = np.diff(mean, prepend=mean[0])  # a level change between two blocks
            z_step = np.abs(_robust_z(step, at_rest, 1e-12))
            reasons["rate offset"] |= (z_step > config.threshold) & (
                np.abs(step) > config.min_rate_dps)
        if acc_var is not None:
            reasons["accel variance"] = _robust_z(np.log(acc_var + 1e-30), at_rest,
                                                  0.05) > config.threshold
        at_rest = ~np.logical_or.reduce(list(reasons.values()))
    level = _level_changes(stats, at_rest, half, config)
    reasons["rate offset"] |= level
    at_rest &= ~level
    motion = ~at_rest
    guard = round(config.guard_s / block_s)
    if guard and motion.any():
        motion = np.convolve(motion.astype(np.int8), np.ones(2 * guard + 1, np.int8),
                             mode="same") > 0
    row_motion = _rows_of(motion, starts, n)
    short = np.zeros(n, dtype=bool)
    for a, b in _spans(~row_motion):
        if t[b - 1] - t[a] < config.min_segment_s:
            short[a:b] = True
    rest = ~row_motion & ~short
    row_reasons = {k: _rows_of(v, starts, n) for k, v in reasons.items()}
    row_reasons["guard"] = row_motion & ~np.logical_or.reduce(list(row_reasons.values()))
    row_reasons["short rest"] = short
    segments = []
    for a, b in _spans(~rest):
        why = tuple(k for k, v in row_reasons.items() if v[a:b].any())
        segments.append(ExcludedSegment(float(t[a]), float(t[b - 1]), why))
    row_dt = np.append(np.diff(t), dt)
    noise = {a: float(np.sqrt(np.median(var[at_rest] if at_rest.any() else var)))
             for a, (_, var) in stats.items()}
    return RestReport(run=name, rest=rest, segments=tuple(segments),
                      excluded_s=float(np.sum(row_dt[~rest])), total_s=float(np.sum(row_dt)),
                      noise_dps=noise)


def rest_of_run(run: Run, config: RestConfig | None = None, *,
                short: str = "refuse") -> RestReport:
    """:func:`detect_rest` on a run, with its accelerometer when ``Run.extra`` has
    ``accel_x_mps2``, ``accel_y_mps2`` and ``accel_z_mps2``.

    A run with fewer than 2 × ``min_rows`` rows: ``short="refuse"`` raises
    ConfigError (as :func:`detect_rest`), ``short="keep"`` returns a report with every
    row at rest and a ``note`` saying why."""
    config = config or RestConfig()
    if short == "keep" and len(run) < 2 * config.min_rows:
        t = run.time_s
        return RestReport(run=run.name, rest=np.ones(len(run), dtype=bool), segments=(),
                          excluded_s=0.0, total_s=float(t[-1] - t[0]) if len(t) else 0.0,
                          noise_dps={}, note=f"{len(run)} rows, too few for rest detection "
                          f"(at least {2 * config.min_rows}): every row used")
    accel = None
    if all(k in run.extra for k in ACCEL_KEYS):
        x, y, z = (run.extra[k] for k in ACCEL_KEYS)
        accel = (x, y, z)
    return detect_rest(run.time_s, run.rates_dps, accel_mps2=accel, config=config,
                       name=run.name)
