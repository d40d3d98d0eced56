"""Preparing runs for the diagnosis: sensor settings, T/ΔT features, 1-s blocks.

Per run (one rate axis):

1. the temperature readout is characterised from the readings themselves:
   update period (the shortest interval between changes that recurs), LSB
   (the grid the readings sit on) and white noise (from successive fresh
   readings);
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


def characterise(run: Run, axis: str) -> Readout:
    """Readout period, LSB and noise of the temperature sensor; rate LSB and noise."""
    t = run.time_s
    if len(t) < 10:
        raise CalibrationError(f"{run.source}: run {run.name!r} has {len(t)} rows, need ≥ 10")
    dt = float(np.median(np.diff(t)))
    temp = run.temperature_c
    change = np.flatnonzero(np.diff(temp) != 0) + 1
    period = dt
    if len(change) > 10:
        gaps = np.diff(t[change])
        period = max(dt, float(np.percentile(gaps, 10)))
        period = dt * round(period / dt) if period > 1.5 * dt else dt
    refresh = period
    if period > 1.5 * dt:  # Σ gaps / Σ refreshes they span: first over gaps of ≤ 3
        gaps = np.diff(t[change])  # refreshes (robust to the grid's rounding), then ≤ 10
        for limit in (3.5, 10.0):
            g = gaps[gaps < limit * refresh]
            k = np.round(g / refresh)
            if np.sum(k) > 0:
                refresh = float(np.sum(g) / np.sum(k))
    fresh_idx = np.r_[0, change] if period > 1.5 * dt else np.arange(len(t))
    lsb = _grid_step(temp[: min(len(temp), 200_000)], floor=1e-7)
    fresh = temp[fresh_idx]
    noise = float(np.std(np.diff(fresh)) / math.sqrt(2)) if len(fresh) > 3 else 0.02
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
    )


def estimator_for(readouts: Sequence[Readout], tau_s: float = DEFAULT_TAU_S) -> EstimatorConfig:
    """Estimator settings matching the readout: fed once per max(period, 1 s)."""
    period = max(float(np.median([r.refresh_period_s or r.period_s for r in readouts])),
                 BLOCK_S)
    lsb = float(np.median([r.lsb_c for r in readouts]))
    noise = float(np.median([r.noise_c for r in readouts]))
    # a quantised, noiseless-looking reading: its noise is the quantisation itself
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
