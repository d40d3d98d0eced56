"""Test helper: motion injected into simulated static runs at known times."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gyrotherm.codecs import Run


def with_rotations(run: Run, intervals: tuple[tuple[float, float], ...], *,
                   accel: bool = False, seed: int = 0) -> Run:
    """``run`` turned about x and z during ``intervals`` (s): one-sided half-sine rate
    profiles of 60 °/s and 20 °/s peak (non-zero mean, so a fit that keeps them is
    biased); with ``accel``, an accelerometer at rest reading g with 0.02 m/s² noise,
    shaken by 2 m/s² during the turns."""
    t = run.time_s
    rates = {a: v.copy() for a, v in run.rates_dps.items()}
    rng = np.random.default_rng(seed)
    acc = np.zeros((3, len(t)))
    acc[2] = 9.80665
    acc += rng.standard_normal(acc.shape) * 0.02
    for a, b in intervals:
        m = (t >= a) & (t < b)
        u = (t[m] - a) / (b - a)
        rates["x"][m] += 60.0 * np.sin(np.pi * u)
        rates["z"][m] += 20.0 * np.sin(np.pi * u) ** 2
        acc[:, m] += rng.standard_normal((3, int(m.sum()))) * 2.0
    extra = dict(run.extra)
    if accel:
        extra.update(accel_x_mps2=acc[0], accel_y_mps2=acc[1], accel_z_mps2=acc[2])
    return Run(name=run.name + "-moving", time_s=t, temperature_c=run.temperature_c,
               rates_dps=rates, chamber_c=run.chamber_c, true_bias_dps=run.true_bias_dps,
               metadata=run.metadata, extra=extra)


def truth_rms(cal_path: Path, runs: Sequence[Run], turns_s: Sequence[tuple[float, float]],
              *, guard_s: float = 2.0) -> float:
    """Mean over axes and runs of RMS(bias removed − true bias), °/s, on the rows at
    rest (each turn ± ``guard_s`` left out), with the calibration's own estimator."""
    from dataclasses import replace

    from gyrotherm.compensation import features, load_calibration, score

    cal = load_calibration(cal_path)
    vals = []
    for run in runs:
        still = np.ones(len(run), dtype=bool)
        for a, b in turns_s:
            still &= ~((run.time_s >= a - guard_s) & (run.time_s < b + guard_s))
        f = replace(features(run, cal.estimator), rest=still)
        vals += [s.truth.rms_dps for s in score(cal, f) if s.truth is not None]
    return float(np.mean(vals))
