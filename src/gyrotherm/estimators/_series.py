"""The estimator over a recorded series: the same filter, at flight-log scale.

:class:`~gyrotherm.estimators.TemperatureEstimator` wraps filterpy's generic
``KalmanFilter``: about 100 µs per reading in matrix calls, 6 min for a 1-hour
1 kHz log whose every row is fed. :func:`estimate_series` runs the *same*
filter — same model, same gating, re-initialisations and time rules, same
caching of ``F``/``Q`` — written out for the 2-state case in float arithmetic
(≈ 3 µs per reading). Tests check it against the filterpy estimator row by
row to 1e-9 (``tests/estimators/test_series.py``); the daemon keeps filterpy.

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


class _Filter:
    """:class:`TemperatureEstimator`'s ``_fuse`` for a 2-state filter in floats."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        self.cfg = cfg
        self.r = cfg.measurement_variance_c2
        self.gate2 = cfg.gate_sigma**2
        self.q = cfg.process_noise_c2_per_s3
        self.time_s: float | None = None
        self.x0 = self.x1 = 0.0
        self.p00 = self.p01 = self.p10 = self.p11 = 0.0
        self.rejections = 0
        self.dt = math.nan  # the cached F/Q: for this dt
        self.q00 = self.q01 = self.q11 = 0.0
        self.fdt = 0.0

    def init(self, time_s: float, z: float) -> None:
        self.x0, self.x1 = z, 0.0
        self.p00, self.p01 = self.r, 0.0
        self.p10, self.p11 = 0.0, self.cfg.initial_rate_std_c_per_s**2
        self.time_s = time_s
        self.rejections = 0

    def finite(self) -> bool:
        return math.isfinite(self.x0 + self.x1) and math.isfinite(
            self.p00 + self.p01 + self.p10 + self.p11)

    def predict_to(self, time_s: float) -> None:
        assert self.time_s is not None
        dt = time_s - self.time_s
        if not dt > 0.0:
            return
        if not abs(dt - self.dt) <= 1e-9 * dt:  # same reuse rule as the estimator
            self.fdt = dt
            self.q00 = self.q * (dt**3 / 3.0)
            self.q01 = self.q * (dt**2 / 2.0)
            self.q11 = self.q * dt
            self.dt = dt
        f = self.fdt
        p00, p01, p10, p11 = self.p00, self.p01, self.p10, self.p11
        self.x0 = self.x0 + f * self.x1
        a00, a01 = p00 + f * p10, p01 + f * p11  # F P
        self.p00 = a00 + a01 * f + self.q00
        self.p01 = a01 + self.q01
        self.p10 = p10 + p11 * f + self.q01
        self.p11 = p11 + self.q11
        self.time_s = time_s

    def fuse(self, time_s: float, z: float) -> None:
        if not math.isfinite(z) or not math.isfinite(time_s):
            return
        if self.time_s is None:
            self.init(time_s, z)
            return
        if time_s < self.time_s - self.cfg.stale_after_s or time_s > self.time_s + MAX_PREDICT_S:
            self.init(time_s, z)
            return
        self.predict_to(time_s)
        if not self.finite():
            self.init(time_s, z)
            return
        y = z - self.x0
        s = self.p00 + self.r
        if y * y > self.gate2 * s:
            self.rejections += 1
            if self.rejections >= self.cfg.max_consecutive_rejections:
                self.init(max(time_s, self.time_s), z)
            return
        si = 1.0 / s
        k0, k1 = self.p00 * si, self.p10 * si
        self.x0 += k0 * y
        self.x1 += k1 * y
        p00, p01, p10, p11 = self.p00, self.p01, self.p10, self.p11
        i00 = 1.0 - k0  # I − kH = [[i00, 0], [−k1, 1]]
        a00, a01 = i00 * p00, i00 * p01
        a10, a11 = p10 - k1 * p00, p11 - k1 * p01
        r = self.r
        self.p00 = a00 * i00 + k0 * r * k0
        self.p01 = a01 - a00 * k1 + k0 * r * k1
        self.p10 = a10 * i00 + k1 * r * k0
        self.p11 = a11 - a10 * k1 + k1 * r * k1
        if not self.finite():
            self.init(max(time_s, self.time_s), z)
            return
        self.rejections = 0


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
    kf = _Filter(config)
    temp, rate = math.nan, math.nan
    prev_slot = math.nan
    for start in range(0, n, _BLOCK_ROWS):
        stop = min(n, start + _BLOCK_ROWS)
        times = times_all[start:stop].tolist()
        readings = readings_all[start:stop].tolist()
        if period > 0:  # row i is fed when it opens a new slot floor(t/P)
            slot = np.floor(times_all[start:stop] / period + 1e-9)
            fed = np.r_[slot[0] != prev_slot, slot[1:] != slot[:-1]].tolist()
            prev_slot = float(slot[-1])
        else:
            fed = [True] * (stop - start)
        t_block = t_out[start:stop]
        r_block = r_out[start:stop]
        for i in range(stop - start):
            if fed[i]:
                kf.fuse(times[i], readings[i])
                temp, rate = kf.x0, kf.x1
            t_block[i] = temp
            r_block[i] = rate
    return EstimateSeries(temperature_c=t_out, delta_t_c=config.tau_s * r_out, rate_c_per_s=r_out)
