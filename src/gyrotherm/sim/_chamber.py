"""Temperature-chamber profiles: set-points and the chamber's realised air temperature.

A profile is a list of set-points (time_s, temperature_c) joined linearly:
holds, heating and cooling ramps, cycles. The realised chamber temperature
adds what a real chamber does (Tang et al. §5, Fig. 6):

* control lag: the air follows the set-point through a first-order lag
  ``lag_s`` (rounded corners);
* ramp non-linearity: on each ramp a bow ``bow_c · sin(π·u)`` (u = fraction of
  the ramp done); a half-sine about its linear fit leaves residuals of
  0.31·|bow_c| standard deviation, so bow_c ≈ 1.9–2.7 °C reproduces the
  0.57–0.84 °C of Fig. 6; with ``bow_rate_exponent`` p ≠ 0 (default 0: off) the bow
  grows with the ramp rate r = |ΔT_set|/Δt (°C/min) as
  ``bow_c · (r / bow_reference_rate_c_per_min)^p``;
* control noise: an Ornstein–Uhlenbeck process of standard deviation
  ``noise_c`` and correlation time ``noise_tau_s`` (stability ±0.2 °C ≈ 2σ).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from gyrotherm._errors import ConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SetPoint:
    """Chamber set-point ``temperature_c`` (°C) at ``time_s`` (s since power-on)."""

    time_s: float
    temperature_c: float


@dataclass(frozen=True)
class ChamberModel:
    """How the real chamber departs from its set-points."""

    lag_s: float = 30.0
    bow_c: float = 2.2
    noise_c: float = 0.1
    noise_tau_s: float = 20.0
    bow_rate_exponent: float = 0.0
    bow_reference_rate_c_per_min: float = 1.0

    def __post_init__(self) -> None:
        if not self.bow_reference_rate_c_per_min > 0:
            raise ConfigError("chamber: bow_reference_rate_c_per_min must be > 0, got "
                              f"{self.bow_reference_rate_c_per_min!r}")

    def bow_for_rate_c(self, rate_c_per_min: float) -> float:
        """Bow amplitude (°C) of a ramp at ``rate_c_per_min`` (°C/min, sign ignored)."""
        if self.bow_rate_exponent == 0.0:
            return self.bow_c
        ratio = abs(rate_c_per_min) / self.bow_reference_rate_c_per_min
        return float(self.bow_c * ratio**self.bow_rate_exponent)


@dataclass(frozen=True)
class ChamberProfile:
    """Set-points joined linearly; the first at time 0."""

    setpoints: tuple[SetPoint, ...]

    def __post_init__(self) -> None:
        pts = self.setpoints
        if len(pts) < 2:
            raise ConfigError("chamber profile: need at least two set-points")
        if pts[0].time_s != 0.0:
            raise ConfigError(f"chamber profile: first set-point at {pts[0].time_s} s, not 0 s")
        for a, b in pairwise(pts):
            if b.time_s <= a.time_s:
                raise ConfigError(
                    f"chamber profile: set-point times must increase ({a.time_s} then {b.time_s})"
                )
        for p in pts:
            if not -100.0 <= p.temperature_c <= 200.0:
                raise ConfigError(
                    f"chamber profile: set-point {p.temperature_c} °C outside [-100, 200] °C"
                )

    @classmethod
    def from_pairs(cls, pairs: Sequence[tuple[float, float]]) -> ChamberProfile:
        return cls(tuple(SetPoint(float(t), float(c)) for t, c in pairs))

    @property
    def duration_s(self) -> float:
        return self.setpoints[-1].time_s

    def setpoint_c(self, time_s: FloatArray) -> FloatArray:
        """Set-point temperature at ``time_s`` (linear between set-points)."""
        ts = [p.time_s for p in self.setpoints]
        cs = [p.temperature_c for p in self.setpoints]
        return np.interp(time_s, ts, cs)

    def realise(
        self, time_s: FloatArray, model: ChamberModel, rng: np.random.Generator
    ) -> FloatArray:
        """Realised chamber air temperature (°C) on the regular grid ``time_s``."""
        dt = float(time_s[1] - time_s[0])
        target = self.setpoint_c(time_s)
        for a, b in pairwise(self.setpoints):
            if a.temperature_c != b.temperature_c:
                on = (time_s >= a.time_s) & (time_s <= b.time_s)
                u = (time_s[on] - a.time_s) / (b.time_s - a.time_s)
                rate_c_per_min = (b.temperature_c - a.temperature_c) / (b.time_s - a.time_s) * 60
                target[on] += model.bow_for_rate_c(rate_c_per_min) * np.sin(np.pi * u)
        air = first_order(target, dt, model.lag_s, target[0])
        if model.noise_c > 0:
            air += ou_process(len(time_s), dt, model.noise_c, model.noise_tau_s, rng)
        return air


def first_order(u: FloatArray, dt: float, tau_s: float, y0: float) -> FloatArray:
    """y' = (u − y)/τ, exact for u held over each step, starting at y0."""
    if tau_s <= 0:
        return u.copy()
    a = np.exp(-dt / tau_s)
    y, _ = lfilter([1 - a], [1, -a], u, zi=[a * y0])
    return np.asarray(y, dtype=np.float64)


def ou_process(
    n: int, dt: float, sigma: float, tau_s: float, rng: np.random.Generator
) -> FloatArray:
    """Stationary Ornstein–Uhlenbeck (first-order Gauss–Markov) samples, std ``sigma``."""
    a = np.exp(-dt / tau_s)
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - a * a)
    x0 = rng.standard_normal() * sigma
    y, _ = lfilter([1.0], [1, -a], w, zi=[a * x0])
    return np.asarray(y, dtype=np.float64)


