"""Do two IMUs agree? Per pair, time-aligned differences of corrected rates per window.

Autopilots vote between IMUs on raw rates; the daemon, which corrects each IMU's
thermal bias, can say more: after compensation two healthy IMUs on one vehicle
measure the same rotation, so the difference of their corrected rates is their
noise plus what the calibrations leave (≈ 0.01–0.05 °/s), whatever the vehicle does.

For each pair (a, b) in configuration order (a first), each corrected rate of a
(:attr:`gyrotherm.daemon.Pipeline.rate_tap`, on the daemon's receive clock) is
paired with b's latest one when they are at most ``max_skew_s`` apart (IMUs on one
bus at the same rate: the previous frame of b, < 1 ms); per axis the window
accumulates n, Σd, Σd². At each window's end (``window_s``, checked by the
housekeeping at least every 0.25 s), per axis:

* ``mean_dps`` = Σd / n, the disagreement;
* ``noise_dps`` = s_d / √n, the standard error of that mean from the differences'
  own scatter s_d (both IMUs' white noise, and motion the alignment does not
  cancel);
* ``limit_dps`` = ``tolerance_dps`` + ``k_sigma`` · ``noise_dps``;
* the axis is **inconsistent** when |mean| > limit.

With fewer than ``min_samples`` aligned pairs the window says NO_DATA (one of the
two is silent, or its rates are not aligned with the other's). A bias step Δ on
one axis of one IMU is flagged from the first whole window after it when
Δ > limit, i.e. within 2 · ``window_s`` + 0.25 s of the step.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from gyrotherm.codecs._wire_consistency import (
    AXIS_FLAGS,
    ConsistencyFlags,
    ConsistencyMessage,
)
from gyrotherm.daemon._pipeline import RateTap
from gyrotherm.daemon._vehicle import ConsistencyConfig


class Consistency:
    """The consistency check of ``sensors`` (module docstring); not thread-safe."""

    def __init__(self, sensors: Sequence[str], config: ConsistencyConfig) -> None:
        self.sensors = tuple(sensors)
        self.config = config
        n = len(self.sensors)
        self.pairs = [(a, b) for a in range(n) for b in range(a + 1, n)]
        self._latest = [[-math.inf, 0.0, 0.0, 0.0] for _ in range(n)]
        self._acc = {p: [0.0] * 7 for p in self.pairs}  # n, Σdx, Σdy, Σdz, Σdx², Σdy², Σdz²
        self._window_start: float | None = None
        self.seq = {p: 0 for p in self.pairs}

    def tap(self, index: int) -> RateTap:
        """The rate observer of IMU ``index``."""
        latest = self._latest
        mine = latest[index]
        partners = [(latest[b], self._acc[(a, b)]) for a, b in self.pairs if a == index]
        skew = self.config.max_skew_s

        def on_rate(t: float, x: float, y: float, z: float) -> None:
            mine[0], mine[1], mine[2], mine[3] = t, x, y, z
            for other, acc in partners:
                if -skew <= t - other[0] <= skew:
                    dx, dy, dz = x - other[1], y - other[2], z - other[3]
                    acc[0] += 1.0
                    acc[1] += dx
                    acc[2] += dy
                    acc[3] += dz
                    acc[4] += dx * dx
                    acc[5] += dy * dy
                    acc[6] += dz * dz

        return on_rate

    def poll(self, now_s: float) -> list[ConsistencyMessage]:
        """At housekeeping (wall clock ``now_s``): one message per pair when a window ended."""
        start = self._window_start
        if start is None:
            self._window_start = now_s
            return []
        if now_s - start < self.config.window_s:
            return []
        self._window_start = now_s
        out = []
        for pair in self.pairs:
            acc = self._acc[pair]
            out.append(self._verdict(pair, acc, now_s, now_s - start))
            acc[:] = [0.0] * 7
            self.seq[pair] += 1
        return out

    def _verdict(self, pair: tuple[int, int], acc: list[float], now_s: float,
                 window_s: float) -> ConsistencyMessage:
        c = self.config
        n = int(acc[0])
        mean, noise, limit = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        flags = ConsistencyFlags.NONE
        if n < c.min_samples:
            flags |= ConsistencyFlags.NO_DATA
            mean = noise = limit = [math.nan] * 3
        else:
            for j in range(3):
                s, ss = acc[1 + j], acc[4 + j]
                mean[j] = s / n
                var = max(0.0, (ss - s * s / n) / (n - 1))
                noise[j] = math.sqrt(var / n)
                limit[j] = c.tolerance_dps + c.k_sigma * noise[j]
                if not abs(mean[j]) <= limit[j]:  # NaN: inconsistent
                    flags |= AXIS_FLAGS[j]
        a, b = pair
        return ConsistencyMessage(self.seq[pair], now_s, window_s, self.sensors[a],
                                  self.sensors[b], n, (mean[0], mean[1], mean[2]),
                                  (noise[0], noise[1], noise[2]), (limit[0], limit[1], limit[2]),
                                  flags)
