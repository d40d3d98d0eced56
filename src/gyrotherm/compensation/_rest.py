"""Rest detection: which rows of a log show the gyro at rest, so that only those feed a fit.

A bias fit needs the true rate to be zero; a log with motion (a flight, a hand-held
turn, a vehicle driven about) must have its moving rows left out. They are *masked*,
not cut: ΔT = τ·dT/dt is estimated over the whole run (the estimator needs the
temperature history through the motion), and the fit then skips the masked rows
(:class:`gyrotherm.compensation.RunFeatures` ``rest``). ``fit``, ``evaluate``,
``diagnose`` and ``export`` all call :func:`rest_of_run` with one :class:`RestConfig`.

**Physical limits** (the constants below, units in their names), which hold whatever
the rest of the log does, so that a log in motion throughout keeps nothing:

* a row whose rate magnitude √(ω_x² + ω_y² + ω_z²) exceeds ``max_rate_dps`` (5 °/s: a
  MEMS gyro's bias is well under it, a turn is not) is motion ("rate above");
* a row logged while the vehicle is armed (``Run.extra["armed"]`` = 1, from the log's
  arming state) is not rest ("armed"), turning or not: motors running or about to;
* a block whose mean accelerometer magnitude |a| is off g by more than
  ``max_accel_g_error_mps2`` is motion ("accel not 1 g": a sustained acceleration);
* a block whose rate standard deviation exceeds ``max_rate_std_dps`` on an axis, or its
  |a| standard deviation ``max_accel_std_mps2``, is motion ("rate variance", "accel
  variance");
* a **logging gap** (a step between rows longer than ``gap_s``, or ``gap_median_factor``
  median row periods) ends a rest stretch: no block spans one, the minimum stretch is
  met on each side alone, and a piece between gaps shorter than a block is left out
  ("logging gap").

**Statistical tests** against the gyro's own noise, on consecutive blocks b of
``window_s`` seconds (n_b ≥ ``min_rows`` rows), per rate axis a (°/s) and the
accelerometer (m/s²) when the run has one:

* rate variance  v_ab = (1/n_b) Σ (ω_i − ω̄_ab)², tested as ln v_ab;
* high-pass rate h_ab = ω̄_ab − median_{|b'−b| ≤ K} ω̄_ab', tested as |z|, the block mean minus a
  running median over ± ``baseline_s`` of rest blocks (a constant-rate turn has no
  variance but an offset; the slow thermal drift of the bias passes the median);
* rate steps  s_ab = ω̄_ab − ω̄_a(b−1) (a level change, even on a block boundary);
* accelerometer magnitude variance  ln var_b(|a|);
* rate level of whole rest stretches against their neighbours' (a constant-rate turn
  longer than the running median has neither variance nor offset inside).

Each feature f is scored robustly: z_b = (f_b − m)/s with m = median and s = 1.4826·MAD
of f over the blocks judged at rest (two passes: the blocks within the physical limits,
then the rest blocks of the first pass). A block is in motion when any z_b exceeds
``threshold``, and, for the rate features, the rate deviation also exceeds
``min_rate_dps`` (so that a noise-free simulated gyro is not declared moving by its own
rounding). Motion blocks are widened by ``guard_s`` on each side, and rest stretches
shorter than the minimum are excluded too ("short rest"). The minimum is
``min_segment_s``, or ``min_segment_fraction`` of the time the log covers when that is
shorter (a still log of 25 s is kept whole; the report's note says so).

A run with fewer than 2 × ``min_rows`` rows gets the physical limits only (a note says so).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run
from gyrotherm.compensation import _restblocks as rb

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
ACCEL_KEYS = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
"""``Run.extra`` columns of the accelerometer, m/s² (written by gyrotherm.readers)."""
ARMED_KEY = "armed"
"""``Run.extra`` column of the vehicle's arming state per row: 1 armed, 0 disarmed."""
STANDARD_GRAVITY_MPS2 = 9.80665

REST_WINDOW_S = 1.0
REST_MIN_ROWS = 5
REST_THRESHOLD_Z = 6.0
REST_BASELINE_S = 20.0
REST_GUARD_S = 1.0
REST_MIN_SEGMENT_S = 30.0
REST_MIN_SEGMENT_FRACTION = 0.5
"""Of the time the log covers: the minimum rest stretch of a log shorter than 60 s."""
REST_MIN_RATE_DPS = 0.05
REST_MAX_RATE_DPS = 5.0
REST_MAX_RATE_STD_DPS = 2.0
REST_MAX_ACCEL_STD_MPS2 = 0.5
REST_MAX_ACCEL_G_ERROR_MPS2 = 2.0
REST_GAP_S = 1.0
REST_GAP_MEDIAN_FACTOR = 2.5


@dataclass(frozen=True)
class RestConfig:
    """Rest-detection settings (units in the names; see the module docstring)."""

    window_s: float = REST_WINDOW_S
    min_rows: int = REST_MIN_ROWS
    threshold: float = REST_THRESHOLD_Z
    baseline_s: float = REST_BASELINE_S
    guard_s: float = REST_GUARD_S
    min_segment_s: float = REST_MIN_SEGMENT_S
    min_segment_fraction: float = REST_MIN_SEGMENT_FRACTION
    min_rate_dps: float = REST_MIN_RATE_DPS
    max_rate_dps: float = REST_MAX_RATE_DPS
    max_rate_std_dps: float = REST_MAX_RATE_STD_DPS
    max_accel_std_mps2: float = REST_MAX_ACCEL_STD_MPS2
    max_accel_g_error_mps2: float = REST_MAX_ACCEL_G_ERROR_MPS2
    gap_s: float = REST_GAP_S
    gap_median_factor: float = REST_GAP_MEDIAN_FACTOR

    def __post_init__(self) -> None:
        for name in ("window_s", "threshold", "baseline_s", "max_rate_dps",
                     "max_rate_std_dps", "max_accel_std_mps2", "max_accel_g_error_mps2",
                     "gap_s", "gap_median_factor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"rest.{name} must be a positive number, got {v!r}")
        for name in ("guard_s", "min_segment_s", "min_rate_dps"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ConfigError(f"rest.{name} must be a number >= 0, got {v!r}")
        if not 0 < self.min_segment_fraction <= 1:
            raise ConfigError("rest.min_segment_fraction must be in (0, 1], got "
                              f"{self.min_segment_fraction!r}")
        if self.min_rows < 2:
            raise ConfigError(f"rest.min_rows must be >= 2, got {self.min_rows!r}")

    def physical_reasons(self) -> dict[str, str]:
        """The row-level limits' reason names, as the reports give them."""
        return {"rate": f"rate above {self.max_rate_dps:g} °/s", "armed": "armed",
                "accel": "accel not 1 g"}


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
    """What the reader should know: the statistics did not run (too few rows), or the
    minimum rest stretch was shortened to fit a short log."""
    min_segment_s: float = REST_MIN_SEGMENT_S
    """The minimum rest stretch applied, s."""
    gaps: int = 0
    """Logging gaps found (each ends a rest stretch)."""
    tested: bool = True
    """False when the run was too short for the statistical tests."""

    @property
    def excluded_fraction(self) -> float:
        return float(1.0 - np.mean(self.rest)) if len(self.rest) else 0.0

    def to_dict(self) -> dict[str, object]:
        return {"run": self.run, "rows": len(self.rest),
                "excluded_rows": int(np.count_nonzero(~self.rest)),
                "excluded_s": self.excluded_s, "total_s": self.total_s,
                "excluded_fraction": self.excluded_fraction,
                "min_segment_s": self.min_segment_s, "gaps": self.gaps,
                "noise_dps": dict(self.noise_dps),
                "segments": [s.to_dict() for s in self.segments],
                **({"note": self.note} if self.note else {})}


def _segments(t: FloatArray, rest: BoolArray, row_reasons: Mapping[str, BoolArray]
              ) -> tuple[ExcludedSegment, ...]:
    return tuple(ExcludedSegment(float(t[a]), float(t[b - 1]),
                                 tuple(k for k, v in row_reasons.items() if v[a:b].any()))
                 for a, b in rb.spans(~rest))


def _too_few(t: FloatArray, physical: Mapping[str, BoolArray], dt: float,
             config: RestConfig, name: str) -> RestReport:
    """A run too short for the statistics: every row kept but those over a physical limit."""
    n = len(t)
    rest = ~np.logical_or.reduce(list(physical.values())) if n else np.ones(0, bool)
    dropped = int(np.count_nonzero(~rest))
    which = ", ".join(k for k, v in physical.items() if v.any())
    used = f"every row used but {dropped} ({which})" if dropped else "every row used"
    row_dt = np.append(np.diff(t), dt) if n else np.zeros(0)
    return RestReport(run=name, rest=rest, segments=_segments(t, rest, physical),
                      excluded_s=float(np.sum(row_dt[~rest])), total_s=float(np.sum(row_dt)),
                      noise_dps={}, tested=False,
                      note=f"{n} rows, too few for rest detection (at least "
                      f"{2 * config.min_rows}): {used}")


def detect_rest(
    time_s: FloatArray,
    rates_dps: Mapping[str, FloatArray],
    *,
    accel_mps2: tuple[FloatArray, FloatArray, FloatArray] | None = None,
    armed: FloatArray | None = None,
    config: RestConfig | None = None,
    name: str = "",
    short: str = "refuse",
) -> RestReport:
    """Rest mask of a run's rows from its rates (°/s) and, optionally, its accelerometer
    (m/s²) and arming state (1 armed, 0 not). A run with fewer than 2 × ``min_rows``
    rows: ``short="refuse"`` raises ConfigError, ``short="keep"`` applies the physical
    limits only, with a note."""
    config = config or RestConfig()
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    acc_mag = None
    if accel_mps2 is not None:
        acc_mag = np.sqrt(sum(np.asarray(c, dtype=np.float64) ** 2 for c in accel_mps2))
    physical = rb.physical_rows(rates_dps, armed, config)
    if n < 2 * config.min_rows:
        if short == "keep":
            return _too_few(t, physical, dt, config, name)
        raise ConfigError(f"run {name!r}: {n} rows are too few for rest detection "
                          f"(at least {2 * config.min_rows}); use --rest all")
    pieces = rb.piece_starts(t, dt, config)
    starts = rb.blocks(n, pieces, dt, config)
    block_rows = np.diff(np.append(starts, n))
    block_s = float(np.median(block_rows)) * dt
    half = max(1, round(config.baseline_s / block_s))
    breaks = np.searchsorted(starts, pieces).astype(np.intp)  # block index after each gap
    piece_of = np.searchsorted(pieces, starts, side="right") - 1
    piece_len = np.diff(np.append(pieces, n))[piece_of]
    isolated = piece_len < config.min_rows  # a piece between gaps shorter than a block
    stats = {a: rb.block_stats(np.asarray(v, dtype=np.float64), starts)
             for a, v in rates_dps.items()}
    hard = {k: rb.block_any(v, starts) for k, v in physical.items()}
    acc_var = None
    if acc_mag is not None:
        acc_mean, acc_var = rb.block_stats(acc_mag, starts)
        acc_mean += float(np.median(acc_mag))  # block_stats centres on the median
        hard[config.physical_reasons()["accel"]] = np.abs(
            acc_mean - STANDARD_GRAVITY_MPS2) > config.max_accel_g_error_mps2
    hard["logging gap"] = isolated
    hard_var = np.logical_or.reduce([var > config.max_rate_std_dps**2
                                     for _, var in stats.values()])
    hard_acc = acc_var > config.max_accel_std_mps2**2 if acc_var is not None else None
    at_rest = ~np.logical_or.reduce([*hard.values(), hard_var,
                                     *([hard_acc] if hard_acc is not None else [])])
    reasons: dict[str, BoolArray] = {}
    for _ in range(2):
        reasons = rb.statistical_reasons(stats, acc_var, at_rest, half, config)
        reasons["rate variance"] |= hard_var
        if hard_acc is not None:
            reasons["accel variance"] |= hard_acc
        reasons.update(hard)
        at_rest = ~np.logical_or.reduce(list(reasons.values()))
    level = rb.level_changes(stats, at_rest, half, config, breaks)
    reasons["rate offset"] |= level
    at_rest &= ~level
    motion = ~at_rest
    guard = round(config.guard_s / block_s)
    if guard and motion.any():
        motion = np.convolve(motion.astype(np.int8), np.ones(2 * guard + 1, np.int8),
                             mode="same") > 0
    row_motion = rb.rows_of(motion, starts, n)
    min_segment, covered = rb.min_segment(t, pieces, dt, config)
    short_rows = np.zeros(n, dtype=bool)
    cut_by_gap = np.zeros(n, dtype=bool)  # short because a gap ends it
    gap_edges = set(pieces[1:].tolist())
    for a, b in rb.spans(~row_motion, pieces):
        if t[b - 1] - t[a] + dt < min_segment:
            short_rows[a:b] = True
            cut_by_gap[a:b] = a in gap_edges or b in gap_edges
    rest = ~row_motion & ~short_rows
    row_reasons = {k: rb.rows_of(v, starts, n) for k, v in reasons.items() if v.any()}
    for k, v in physical.items():  # the rows themselves, not their blocks
        if k in row_reasons:
            row_reasons[k] = v
    row_reasons["guard"] = row_motion & ~np.logical_or.reduce(
        [np.zeros(n, bool), *row_reasons.values()])
    row_reasons["short rest"] = short_rows
    if cut_by_gap.any():
        row_reasons["logging gap"] = row_reasons.get("logging gap", cut_by_gap) | cut_by_gap
    row_dt = np.append(np.diff(t), dt)
    noise = {a: float(np.sqrt(np.median(var[at_rest] if at_rest.any() else var)))
             for a, (_, var) in stats.items()}
    note = ""
    if min_segment < config.min_segment_s:
        note = (f"minimum rest stretch {min_segment:.3g} s, not {config.min_segment_s:g} s: "
                f"the log covers {covered:.3g} s, shorter than "
                f"{config.min_segment_s / config.min_segment_fraction:g} s, so a rest "
                f"stretch needs {config.min_segment_fraction:g} of it")
    return RestReport(run=name, rest=rest, segments=_segments(t, rest, row_reasons),
                      excluded_s=float(np.sum(row_dt[~rest])), total_s=float(np.sum(row_dt)),
                      noise_dps=noise, note=note, min_segment_s=min_segment,
                      gaps=len(pieces) - 1)


def rest_of_run(run: Run, config: RestConfig | None = None, *,
                short: str = "refuse") -> RestReport:
    """:func:`detect_rest` on a run, with its accelerometer when ``Run.extra`` has
    ``accel_x_mps2``, ``accel_y_mps2`` and ``accel_z_mps2``, and its arming state when it
    has ``armed``. ``short`` as :func:`detect_rest`."""
    accel = None
    if all(k in run.extra for k in ACCEL_KEYS):
        x, y, z = (run.extra[k] for k in ACCEL_KEYS)
        accel = (x, y, z)
    return detect_rest(run.time_s, run.rates_dps, accel_mps2=accel,
                       armed=run.extra.get(ARMED_KEY), config=config, name=run.name,
                       short=short)
