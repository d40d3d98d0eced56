"""Confidence intervals for the sweep's rates and parameter errors.

* :func:`wilson`: the Wilson score interval of a proportion k/n (95 % by
  default); unlike the normal approximation it stays inside [0, 1] and is not
  empty at k = 0 (0 of 20 false alarms: [0, 16 %]).
* :func:`bootstrap_quantile`: a quantile of a sample with a seeded percentile
  bootstrap interval (resampling the values with replacement).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

Z95 = 1.959963984540054
BOOTSTRAP_RESAMPLES = 2000


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval (low, high) of k successes in n trials; (0, 1) for n = 0."""
    if n <= 0:
        return 0.0, 1.0
    if not 0 <= k <= n:
        raise ValueError(f"wilson: k = {k} outside [0, {n}]")
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_quantile(
    values: Sequence[float], q: float = 0.5, *, seed: int = 0,
    resamples: int = BOOTSTRAP_RESAMPLES, level: float = 0.95,
) -> tuple[float, float, float]:
    """(estimate, low, high): the ``q`` quantile of ``values`` and its percentile
    bootstrap interval at ``level``; NaNs for an empty sample."""
    v = np.asarray(values, dtype=np.float64)
    if len(v) == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    samples = v[rng.integers(0, len(v), size=(resamples, len(v)))]
    stats = np.quantile(samples, q, axis=1)
    tail = (1.0 - level) / 2.0
    lo, hi = np.quantile(stats, [tail, 1.0 - tail])
    return float(np.quantile(v, q)), float(lo), float(hi)
