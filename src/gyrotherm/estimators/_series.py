"""The estimator over a recorded series: the same filter, at flight-log scale.

:class:`~gyrotherm.estimators.TemperatureEstimator` (the daemon's, online) runs
one reading per call through a typed API; on its filterpy engine it takes about
100 µs per reading in matrix calls, 6 min for a 1-hour 1 kHz log whose every row
is fed. :func:`estimate_series` runs the *same* filter — same model, same gating,
re-initialisations and time rules, same caching of ``F``/``Q`` — written out for
the 2-state case in float arithmetic, as one flat loop over a block of rows
(≈ 3 µs per reading). Tests check it against the filterpy engine row by row to
1e-9 (``tests/estimators/test_series.py``).

Written out, with ``x = [T, Ṫ]``, ``P = [[p00, p01], [p10, p11]]``, ``H = [1, 0]``:

predict over ``dt`` (``F = [[1, dt], [0, 1]]``, ``Q = q·[[dt³/3, dt²/2], [dt²/2, dt]]``)::

    T ← T + dt·Ṫ
    P ← F P Fᵀ + Q

update with reading ``z`` (``R = σ² + LSB²/12``), Joseph form as filterpy::

    y = z − T,  s = p00 + R,  k = [p00, p10] / s
    x ← x + k·y
    P ← (I − kH) P (I − kH)ᵀ + R·k kᵀ

A reading is gated out when ``y² > gate² · s`` (``s`` from the predicted ``P``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gyrotherm.estimators._temperature import MAX_PREDICT_S, EstimatorConfig

FloatArray = NDArray[np.float64]
_BLOCK_ROWS = 1 << 16
"""Rows converted to Python floats at a time (bounded memory on long logs)."""


@dataclass(frozen=True)
class EstimateSeries:
    """Estimator output for every row of a run (held between readings)."""

    temperature_c: FloatArray
    delta_t_c: FloatArray
    rate_c_per_s: FloatArray


@dataclass
class _State:
    """The filter between blocks (``time_s`` None until a finite reading arrives)."""

    time_s: float | None = None
    x0: float = 0.0
    x1: float = 0.0
    p00: float = 0.0
    p01: float = 0.0
    p10: float = 0.0
    p11: float = 0.0
    rejections: int = 0
    dt: float = math.nan
    """The dt of the cached F/Q (reused while dt changes by ≤ 1 ppb, as the estimator)."""


def _run_block(st: _State, cfg: EstimatorConfig, times: list[float], readings: list[float],
               fed: list[bool], t_out: FloatArray, r_out: FloatArray) -> None:
    """:meth:`TemperatureEstimator._fuse` for every fed row, one flat loop over locals
    (the per-row cost of attribute access and calls would triple the time)."""
    r = cfg.measurement_variance_c2
    gate2 = cfg.gate_sigma**2
    q = cfg.process_noise_c2_per_s3
    stale, max_rej = cfg.stale_after_s, cfg.max_consecutive_rejections
    p11_0 = cfg.initial_rate_std_c_per_s**2
    isfinite = math.isfinite
    t0, x0, x1 = st.time_s, st.x0, st.x1
    p00, p01, p10, p11, rej, cdt = st.p00, st.p01, st.p10, st.p11, st.rejections, st.dt
    q00 = q * (cdt**3 / 3.0)
    q01 = q * (cdt**2 / 2.0)
    q11 = q * cdt
    for i in range(len(times)):
        if fed[i]:
            t, z = times[i], readings[i]
            init = False
            if not isfinite(z) or not isfinite(t):
                pass
            elif t0 is None or t < t0 - stale or t > t0 + MAX_PREDICT_S:
                init = True
            else:
                dt = t - t0
                if dt > 0.0:  # predict
                    if not abs(dt - cdt) <= 1e-9 * dt:
                        cdt = dt
                        q00, q01, q11 = q * (dt**3 / 3.0), q * (dt**2 / 2.0), q * dt
                    x0 = x0 + cdt * x1
                    a00, a01 = p00 + cdt * p10, p01 + cdt * p11  # F P
                    p00 = a00 + a01 * cdt + q00
                    p01 = a01 + q01
                    p10 = p10 + p11 * cdt + q01
                    p11 = p11 + q11
                    t0 = t
                if not (isfinite(x0 + x1) and isfinite(p00 + p01 + p10 + p11)):
                    init = True
                else:
                    y = z - x0
                    s = p00 + r
                    if y * y > gate2 * s:
                        rej += 1
                        if rej >= max_rej:
                            init, t = True, max(t, t0)
                    else:
                        si = 1.0 / s
                        k0, k1 = p00 * si, p10 * si
                        x0 += k0 * y
                        x1 += k1 * y
                        i00 = 1.0 - k0  # I − kH = [[i00, 0], [−k1, 1]]
                        a00, a01 = i00 * p00, i00 * p01
                        a10, a11 = p10 - k1 * p00, p11 - k1 * p01
                        p00 = a00 * i00 + k0 * r * k0
                        p01 = a01 - a00 * k1 + k0 * r * k1
                        p10 = a10 * i00 + k1 * r * k0
                        p11 = a11 - a10 * k1 + k1 * r * k1
                        if isfinite(x0 + x1) and isfinite(p00 + p01 + p10 + p11):
                            rej = 0
                        else:
                            init, t = True, max(t, t0)
            if init:
                x0, x1, p00, p01, p10, p11 = z, 0.0, r, 0.0, 0.0, p11_0
                t0, rej = t, 0
        t_out[i] = x0
        r_out[i] = x1
    st.time_s, st.x0, st.x1 = t0, x0, x1
    st.p00, st.p01, st.p10, st.p11, st.rejections, st.dt = p00, p01, p10, p11, rej, cdt


def estimate_series(
    time_s: FloatArray, temperature_c: FloatArray, config: EstimatorConfig
) -> EstimateSeries:
    """Run the estimator over a recorded series, as the daemon would online.

    With ``P = config.update_period_s`` > 0, row i is fed to the filter when it is
    the first row of a new slot ``floor(time_s / P)`` (the simulator's sensor
    refresh and ``gyrotherm sim stream``'s temperature frames use the same
    slots); ``P = 0`` feeds every row. Every row receives the latest estimate
    (T in °C, ΔT = τ·Ṫ in °C, Ṫ in °C/s; the filter's initial zeros until a
    finite reading initialises it, as the filterpy estimator reports).
    Memory: the outputs plus one block of :data:`_BLOCK_ROWS` rows.
    """
    n = len(time_s)
    times_all = np.asarray(time_s, dtype=np.float64)
    readings_all = np.asarray(temperature_c, dtype=np.float64)
    t_out = np.empty(n)
    r_out = np.empty(n)
    period = config.update_period_s
    state = _State()
    prev_slot = math.nan
    for start in range(0, n, _BLOCK_ROWS):
        stop = min(n, start + _BLOCK_ROWS)
        if period > 0:  # row i is fed when it opens a new slot floor(t/P)
            slot = np.floor(times_all[start:stop] / period + 1e-9)
            fed = np.r_[slot[0] != prev_slot, slot[1:] != slot[:-1]].tolist()
            prev_slot = float(slot[-1])
        else:
            fed = [True] * (stop - start)
        _run_block(state, config, times_all[start:stop].tolist(),
                   readings_all[start:stop].tolist(), fed, t_out[start:stop], r_out[start:stop])
    return EstimateSeries(temperature_c=t_out, delta_t_c=config.tau_s * r_out, rate_c_per_s=r_out)
