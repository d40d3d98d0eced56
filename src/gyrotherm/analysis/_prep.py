"""Preparing runs for the diagnosis: sensor settings, T/ΔT features, 1-s blocks.

Per run (one rate axis):

1. the temperature readout is characterised from the readings themselves:
   refresh period (the comb every gap between changes sits on,
   :func:`_refresh_from_changes`), LSB (the grid the readings sit on) and white
   noise (second differences a refresh apart, less the quantisation);
   tests/analysis/test_readout_table.py checks all three against a generator's
   truth over refresh 0.05…1.28 s, LSB 0.0625…1 °C and 10…200 Hz;
2. the product's Kalman estimator (:func:`gyrotherm.estimators.estimate_series`)
   runs over the readings, fed at most once per ``max(update period, 1 s)``,
   giving T and dT/dt; ΔT = τ·dT/dt, where τ is regressed from the logged
   chamber temperature when runs carry ``chamber_c``
   (chamber − T = τ·dT/dt − P, P = self-heating) and defaults to 120 s otherwise
   (the bias models are linear in ΔT, so τ only rescales ΔT coefficients);
3. everything is averaged over 1-s blocks of time since power-on. White noise
   above 0.5 Hz carries no bias information; the blocks make a 1 kHz run and a
   10 Hz run cost the same and give the residual statistics a common footing;
4. the direction of the last temperature move (``direction``: +1 heating,
   −1 cooling, 0 before the first move) is a play operator on T of width
   ``direction_width_c`` (0.25 °C): it flips only after T has moved that far
   from its last extreme, and it keeps its sign through holds (the hysteresis
   regressor then saturates towards it with the temperature travelled, so a
   small wiggle moves it little).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from gyrotherm._errors import CalibrationError
from gyrotherm.analysis._effects import DIRECTION_WIDTH_C, direction_state
from gyrotherm.codecs import Run
from gyrotherm.estimators import EstimatorConfig, estimate_series

FloatArray = NDArray[np.float64]
BLOCK_S = 1.0
DEFAULT_TAU_S = 120.0


@dataclass(frozen=True)
class Readout:
    """What the runs say about the temperature readout and the rate output."""

    period_s: float
    lsb_c: float
    noise_c: float
    sample_rate_hz: float
    rate_lsb_dps: float
    sample_noise_dps: float
    """Per-sample standard deviation of the rate's white part, °/s (first differences / √2)."""
    refresh_period_s: float = 0.0
    """The readout's refresh period, not rounded to the row interval (mean of the single
    refresh intervals, e.g. 1.28 s where ``period_s`` says 1.3 s at 10 Hz), s; 0: unknown."""
    white_noise_c: float = 0.0
    """The readings' white noise σ before rounding, °C (:func:`_white_noise`; 0 where the
    rounding hides it). ``noise_c`` is the scatter between successive *changes* of the
    reading, √(σ² + LSB²/12) or one LSB step (LSB/√2) where the rounding hides σ: the
    quantity the estimator settings, the lag's null replay and the simulator calibration
    were validated with."""


@dataclass(frozen=True)
class Prepared:
    """One run on 1-s blocks: time since power-on, features and the rate of one axis."""

    name: str
    time_s: FloatArray
    temperature_c: FloatArray
    rate_c_per_s: FloatArray
    delta_t_c: FloatArray
    chamber_c: FloatArray | None
    rate_dps: FloatArray
    counts: FloatArray
    direction: FloatArray

    def __len__(self) -> int:
        return len(self.time_s)


def _grid_step(values: FloatArray, *, floor: float) -> float:
    """The grid spacing the values sit on (0 when they do not look quantised)."""
    u = np.unique(np.round(values, 9))
    if len(u) < 3:
        return 0.0
    d = np.diff(u)
    step = float(np.min(d[d > floor])) if np.any(d > floor) else 0.0
    if step <= 0:
        return 0.0
    k = (u - u[0]) / step
    return step if float(np.max(np.abs(k - np.round(k)))) < 0.05 else 0.0


#: Candidate refresh periods scanned per run (log-spaced from 1.5 row intervals to the
#: shortest gap between changes plus one row).
_CANDIDATES = 4000
#: A gap "fits" a candidate P' when it is a whole multiple of P' within this many row
#: intervals (a change is seen at the first row after its refresh: up to one row off
#: per gap, whole rows when the refresh is commensurate with the rows; 10 % for the
#: stamps' jitter).
_FIT_ROWS = 1.1
#: The least share of gaps that must fit.
_FIT_MIN = 0.8
_MAX_GAPS = 5000


def _refresh_from_changes(t: FloatArray, change: NDArray[np.int64], dt: float) -> float:
    """The readout's refresh period from the times its value changed (s).

    A reading can only change at a refresh, so every gap g between two changes is a
    whole multiple n·P of the refresh P, give or take the row grid: a change is seen
    at the first row after its refresh, so each gap is off by less than one row
    interval dt. A quantised, slowly moving temperature repeats its value for several
    refreshes, so the gaps' small percentiles or their minimum give 2P, 5P …, not P.
    Instead each candidate P' (log-spaced, then snapped to the comb it selects: the
    least-squares period of the gaps given their multiples n = round(g/P')) is scored
    by the share F(P') of gaps within :data:`_FIT_ROWS`·dt of a multiple of it. The
    refresh and its divisors P/m fit (almost) every gap; a multiple kP fits only the
    gaps whose stride is a multiple of k (a steady ramp whose value changes every 15
    or 16 refreshes fits none of 7.75P); a candidate off the comb drifts out of
    tolerance over n refreshes. The refresh is
    the *largest* candidate whose F reaches :data:`_FIT_MIN`, refined as
    Σ g / Σ round(g/P) over gaps of ≤ 3 and then ≤ 10 refreshes. Candidates stop at
    the shortest gap plus a row (no refresh is longer); changes on consecutive rows
    (shortest gap one row), or no candidate qualifying, mean every row is fresh
    (refresh = dt): a refresh under 1.5 rows cannot be told from the rows."""
    gaps = np.diff(t[change])
    if len(gaps) > _MAX_GAPS:  # evenly spread: the whole run, bounded cost
        gaps = gaps[np.linspace(0, len(gaps) - 1, _MAX_GAPS).astype(np.int64)]
    lo, hi = 1.5 * dt, float(np.min(gaps)) + dt
    if hi <= lo or np.count_nonzero(gaps < lo) > 0.01 * len(gaps):
        return dt  # changes on consecutive rows: every row is fresh
    tol = _FIT_ROWS * dt
    cand = np.geomspace(lo, hi, _CANDIDATES)
    snapped, fit = np.empty(len(cand)), np.empty(len(cand))
    for i, p in enumerate(cand):  # each candidate snapped to the comb it selects
        n = np.maximum(np.round(gaps / p), 1.0)
        q = float(np.dot(gaps, n) / np.dot(n, n))
        err = gaps - n * q
        snapped[i] = q
        fit[i] = np.count_nonzero(np.abs(err) <= tol) / len(gaps)
    ok = np.flatnonzero((fit >= _FIT_MIN) & (snapped >= lo))
    if len(ok) == 0:
        return dt
    refresh = float(np.max(snapped[ok]))
    for limit in (3.5, 10.0):
        g = gaps[gaps < limit * refresh]
        k = np.round(g / refresh)
        if np.sum(k) > 0:
            refresh = float(np.sum(g) / np.sum(k))
    return refresh


def _white_noise(t: FloatArray, temp: FloatArray, refresh_s: float, lsb_c: float) -> float:
    """White noise of the readings, °C: second differences at a lag of L rows, L·dt the
    refresh rounded up, so that the three readings come from three different refreshes
    (no phase to track: a hold never pairs a reading with itself); a linear trend drops
    out and var = 6σ². Less the quantisation's LSB²/12 (valid while σ ≳ LSB/2; below
    that the rounding hides the noise and LSB/√12 bounds it)."""
    dt = float(np.median(np.diff(t)))
    lag = max(1, math.ceil(refresh_s / dt - 0.01))
    if len(temp) < 2 * lag + 5:
        return 0.02
    d2 = temp[2 * lag:] - 2.0 * temp[lag:-lag] + temp[:-2 * lag]
    total = float(np.var(d2)) / 6.0
    return math.sqrt(max(total - lsb_c * lsb_c / 12.0, 0.0))


def characterise(run: Run, axis: str) -> Readout:
    """Readout period, LSB and noise of the temperature sensor; rate LSB and noise.

    ``refresh_period_s``: :func:`_refresh_from_changes`; ``period_s``: that period on
    the row grid (a multiple of the row interval); ``lsb_c``: the grid the readings sit
    on; ``white_noise_c``: :func:`_white_noise`; ``noise_c``: the scatter between
    changes (the field's docstring)."""
    t = run.time_s
    if len(t) < 10:
        raise CalibrationError(f"{run.source}: run {run.name!r} has {len(t)} rows, need ≥ 10")
    dt = float(np.median(np.diff(t)))
    temp = run.temperature_c
    change = np.flatnonzero(np.diff(temp) != 0) + 1
    refresh = _refresh_from_changes(t, change, dt) if len(change) > 10 else dt
    period = dt * round(refresh / dt) if refresh > 1.5 * dt else dt
    lsb = _grid_step(temp[: min(len(temp), 200_000)], floor=1e-7)
    white = _white_noise(t, temp, refresh, lsb)
    noise = max(math.sqrt(white * white + lsb * lsb / 12.0), lsb / math.sqrt(2)) if lsb > 0 \
        else white
    rate = run.rates_dps[axis]
    rate_lsb = _grid_step(rate[: min(len(rate), 200_000)], floor=1e-9)
    return Readout(
        period_s=period,
        lsb_c=lsb,
        noise_c=min(max(noise, 1e-3), 5.0),
        sample_rate_hz=1.0 / dt,
        rate_lsb_dps=rate_lsb,
        sample_noise_dps=float(np.std(np.diff(rate)) / math.sqrt(2)),
        refresh_period_s=refresh,
        white_noise_c=white,
    )


def estimator_for(readouts: Sequence[Readout], tau_s: float = DEFAULT_TAU_S) -> EstimatorConfig:
    """Estimator settings matching the readout: fed once per max(period, 1 s)."""
    period = max(float(np.median([r.refresh_period_s or r.period_s for r in readouts])),
                 BLOCK_S)
    lsb = float(np.median([r.lsb_c for r in readouts]))
    noise = float(np.median([r.noise_c for r in readouts]))
    # a quantised, noiseless-looking reading: its noise is the quantisation itself (the
    # rule validated in docs/findings.md §5, §6; choosing it by held-out deployed error
    # instead is open)
    noise = max(noise - lsb / math.sqrt(6), 0.005) if lsb > 0 else noise
    return EstimatorConfig(tau_s=tau_s, noise_c=noise, quantisation_c=max(lsb, 1e-4),
                           update_period_s=period)


def _blocks(time_s: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
    idx = np.floor((time_s - time_s[0]) / BLOCK_S).astype(np.int64)
    _, inverse, counts = np.unique(idx, return_inverse=True, return_counts=True)
    return inverse, counts.astype(np.float64)


def _mean(values: FloatArray, inverse: NDArray[np.int64], counts: FloatArray) -> FloatArray:
    return np.bincount(inverse, weights=values, minlength=len(counts)) / counts


def prepare(
    run: Run,
    axis: str,
    estimator: EstimatorConfig,
    *,
    direction_width_c: float = DIRECTION_WIDTH_C,
    features: str = "smooth",
) -> Prepared:
    """Features of ``run`` on 1-s blocks (ΔT with ``estimator.tau_s``).

    ``features="smooth"`` (default): T and dT/dt from a zero-phase
    Savitzky–Golay fit (order 2; 31 s for T, 61 s for dT/dt) to the 1-s block
    means of the readings, so that no estimator lag is mistaken for physics.
    ``features="kalman"``: the product's causal estimator, as the daemon sees it.
    """
    if axis not in run.rates_dps:
        raise CalibrationError(
            f"{run.source}: run {run.name!r} has no rate axis {axis!r} (has {list(run.axes)})"
        )
    inverse, counts = _blocks(run.time_s)
    if features == "kalman":
        est = estimate_series(run.time_s, run.temperature_c, estimator)
        temp = _mean(est.temperature_c, inverse, counts)
        rate_c = _mean(est.rate_c_per_s, inverse, counts)
    elif features == "smooth":
        raw = _mean(run.temperature_c, inverse, counts)
        temp, rate_c = _smooth(raw)
    else:
        raise CalibrationError(f"features = {features!r}: expected 'smooth' or 'kalman'")
    chamber = None if run.chamber_c is None else _mean(run.chamber_c, inverse, counts)
    return Prepared(
        name=run.name,
        time_s=_mean(run.time_s, inverse, counts),
        temperature_c=temp,
        rate_c_per_s=rate_c,
        delta_t_c=estimator.tau_s * rate_c,
        chamber_c=chamber,
        rate_dps=_mean(run.rates_dps[axis], inverse, counts),
        counts=counts,
        direction=direction_state(temp, direction_width_c),
    )


def _smooth(raw: FloatArray) -> tuple[FloatArray, FloatArray]:
    n = len(raw)
    if n < 7:
        return raw.copy(), np.zeros(n)
    w_t = min(31, n - 1 if n % 2 == 0 else n)
    w_d = min(61, n - 1 if n % 2 == 0 else n)
    temp = savgol_filter(raw, w_t, 2, mode="interp")
    rate = savgol_filter(raw, w_d, 2, deriv=1, delta=BLOCK_S, mode="interp")
    return np.asarray(temp, dtype=np.float64), np.asarray(rate, dtype=np.float64)


def with_tau(p: Prepared, tau_s: float) -> Prepared:
    """The same run with ΔT rescaled to the time constant ``tau_s``."""
    from dataclasses import replace

    return replace(p, delta_t_c=tau_s * p.rate_c_per_s)


def fit_tau(runs: Sequence[Prepared]) -> tuple[float, float] | None:
    """τ and self-heating P from chamber − T = τ·dT/dt − P (least squares, all runs).

    None when no run logs the chamber or the temperature never changes.
    """
    rows = [(p.chamber_c - p.temperature_c, p.rate_c_per_s) for p in runs
            if p.chamber_c is not None]
    if not rows:
        return None
    y = np.concatenate([r[0] for r in rows])
    x = np.concatenate([r[1] for r in rows])
    if float(np.std(x)) < 1e-5:
        return None
    a = np.column_stack([x, np.ones_like(x)])
    (tau, c), *_ = np.linalg.lstsq(a, y, rcond=None)
    if not (1.0 <= tau <= 1e5):
        return None
    return float(tau), float(-c)
