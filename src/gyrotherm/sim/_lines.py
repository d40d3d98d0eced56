"""Narrow spectral lines in the rate output: sinusoids of fixed frequency (default: none).

A line k adds ``A_k,axis · sin(2π·f_k·t + φ_k,axis)`` (°/s) to an axis' rate, with a
phase φ drawn uniformly in [0, 2π) per run and axis, so its power is A²/2 at f_k
(a PSD line) and its Allan deviation peaks near τ ≈ 0.371/f_k (IEEE Std 952-1997).
The BMI270 plateaus (docs/findings.md §1) carry such lines, session-specific
(a fan, a pump); the simulator's default gyro has none and draws no random numbers
for them, so default runs are unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SpectralLine:
    """A sinusoid at ``frequency_hz`` with amplitude ``amplitude_dps[axis]`` (°/s, peak)."""

    frequency_hz: float
    amplitude_dps: Mapping[str, float]

    def __post_init__(self) -> None:
        if not (math.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ConfigError(f"spectral line: frequency_hz must be > 0, got "
                              f"{self.frequency_hz!r}")
        for axis, amp in self.amplitude_dps.items():
            if not (math.isfinite(amp) and amp >= 0):
                raise ConfigError(f"spectral line at {self.frequency_hz:g} Hz, axis {axis}: "
                                  f"amplitude_dps must be ≥ 0, got {amp!r}")


def line_signal_dps(
    lines: Sequence[SpectralLine], axis: str, time_s: FloatArray, rng: np.random.Generator
) -> FloatArray:
    """Sum of the lines on ``axis`` at ``time_s`` (°/s); one random phase per line."""
    out = np.zeros_like(time_s)
    for line in lines:
        amp = line.amplitude_dps.get(axis, 0.0)
        phase = rng.uniform(0.0, 2.0 * np.pi)
        out += amp * np.sin(2.0 * np.pi * line.frequency_hz * time_s + phase)
    return out
