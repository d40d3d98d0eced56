"""A vehicle's life for learning in the field: power-ons from different ambients.

Each power-on is a gyro switched on cold at a constant ambient temperature A (°C) and
left at rest while its electronics warm it by ``self_heating_c`` with the die's time
constant ``tau_s`` (T rises from A towards A + S, ΔT = S·e^(−t/τ) falls), for
``warmup_s``; optionally followed by ``motion_s`` of turning (a vehicle that drives off:
rows the learner must leave out). Ambients are drawn uniformly over ``ambient_range_c``
from ``seed``; every power-on has its own switch-on offset and noise stream (seed + k).
The truth columns (``true_bias_dps``, ``true_temperature_c``, ``true_delta_t_c``) are the
simulator's, as for chamber runs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from gyrotherm.codecs import Run
from gyrotherm.sim._chamber import ChamberModel, ChamberProfile
from gyrotherm.sim._gyro import GyroParams, simulate

#: A vehicle computer's enclosure: the die ends ≈ 8 °C above the ambient.
LIFE_GYRO = GyroParams(self_heating_c=8.0, tau_s=120.0)
#: The air around a parked vehicle: no chamber lag or bow, slow small fluctuations.
LIFE_AIR = ChamberModel(lag_s=1.0, bow_c=0.0, noise_c=0.05, noise_tau_s=60.0)


def ambients(n: int, *, ambient_range_c: tuple[float, float] = (-10.0, 40.0),
             seed: int = 0) -> list[float]:
    """``n`` ambient temperatures drawn uniformly over the range (°C), seeded."""
    rng = np.random.default_rng(seed)
    lo, hi = ambient_range_c
    return [float(a) for a in rng.uniform(lo, hi, n)]


def power_on(ambient_c: float, *, gyro: GyroParams = LIFE_GYRO, warmup_s: float = 600.0,
             motion_s: float = 0.0, motion_dps: float = 30.0, rate_hz: float = 10.0,
             seed: int = 0, name: str | None = None) -> Run:
    """One power-on at ``ambient_c``: ``warmup_s`` at rest, then ``motion_s`` turning at
    ``motion_dps`` about z (a sine of 8 s period, added to every axis' measured rate)."""
    duration = warmup_s + motion_s
    profile = ChamberProfile.from_pairs([(0.0, ambient_c), (duration, ambient_c)])
    run = simulate(profile, name=name or f"power-on-{seed}", gyro=gyro, chamber=LIFE_AIR,
                   rate_hz=rate_hz, seed=seed, metadata={"ambient_c": f"{ambient_c:.3f}"})
    if motion_s > 0:
        moving = run.time_s > warmup_s
        turn = motion_dps * np.sin(2 * np.pi * (run.time_s - warmup_s) / 8.0) * moving
        run = replace(run, rates_dps={a: r + turn for a, r in run.rates_dps.items()})
    return run


def life(n: int, *, seed: int = 0, ambient_range_c: tuple[float, float] = (-10.0, 40.0),
         gyro: GyroParams = LIFE_GYRO, warmup_s: float = 600.0,
         rate_hz: float = 10.0) -> list[Run]:
    """``n`` power-ons from ambients drawn with ``seed`` (power-on k uses seed·1000 + k)."""
    return [power_on(a, seed=seed * 1000 + k, name=f"life{seed}-{k:02d}", gyro=gyro,
                     warmup_s=warmup_s, rate_hz=rate_hz)
            for k, a in enumerate(ambients(n, ambient_range_c=ambient_range_c, seed=seed))]


__all__ = ["LIFE_AIR", "LIFE_GYRO", "ambients", "life", "power_on"]
