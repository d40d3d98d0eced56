"""Per-stream accounting of a subscriber: sequence gaps and latency.

* **sequence accounting** (:class:`SequenceTracker`) from ``seq`` (uint64, per key
  expression, 0 first): ``seq == last + 1`` is in order; ``seq > last + 1`` is one
  *gap* of ``seq − last − 1`` *missing* messages; ``seq == last`` a *duplicate*;
  ``seq < last`` a *reset* (the publisher restarted and counts from 0 again; if the
  first seen seq of the new run is ``s > 0`` its ``s`` predecessors count as one
  more gap). The first message seen is never a gap (a late join is not a loss).
* **latency** (:class:`LatencyTracker`, seconds): count, mean, min and max are
  exact; p50/p99 are nearest-rank percentiles (:func:`percentile`) of a uniform
  random sample of at most ``reservoir_size`` latencies (reservoir, Vitter's
  algorithm R, seeded), exact while ``count <= reservoir_size``.

The trackers are not thread-safe: the subscriber calls them from zenoh's one
callback thread.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass

from gyrotherm._errors import ConfigError


@dataclass(frozen=True)
class LatencyStats:
    """Latency summary in seconds; NaN fields while ``count == 0``."""

    count: int
    mean_s: float
    min_s: float
    max_s: float
    p50_s: float
    p99_s: float


def percentile(sorted_values: Sequence[float], pct: float) -> float:
    """Nearest-rank percentile: ``sorted_values[ceil(pct/100·n) − 1]``; NaN when empty."""
    n = len(sorted_values)
    if n == 0:
        return math.nan
    rank = max(1, math.ceil(pct / 100.0 * n))
    return sorted_values[min(rank, n) - 1]


class LatencyTracker:
    """Running latency statistics with a bounded reservoir for the percentiles."""

    def __init__(self, *, reservoir_size: int = 4096, seed: int = 0) -> None:
        if reservoir_size < 1:
            raise ConfigError(f"reservoir_size = {reservoir_size} is invalid: must be >= 1")
        self._size = reservoir_size
        self._rng = random.Random(seed)
        self._reservoir: list[float] = []
        self._count = 0
        self._sum = 0.0
        self._min = math.inf
        self._max = -math.inf

    def add(self, latency_s: float) -> None:
        """Record one latency (s)."""
        self._count += 1
        self._sum += latency_s
        self._min = min(self._min, latency_s)
        self._max = max(self._max, latency_s)
        if len(self._reservoir) < self._size:
            self._reservoir.append(latency_s)
        else:
            j = self._rng.randrange(self._count)
            if j < self._size:
                self._reservoir[j] = latency_s

    def snapshot(self) -> LatencyStats:
        """Current statistics."""
        if self._count == 0:
            return LatencyStats(0, math.nan, math.nan, math.nan, math.nan, math.nan)
        ordered = sorted(self._reservoir)
        return LatencyStats(
            self._count,
            self._sum / self._count,
            self._min,
            self._max,
            percentile(ordered, 50.0),
            percentile(ordered, 99.0),
        )


class SequenceTracker:
    """Gap / reset accounting of one stream's ``seq`` (rules in the module docstring)."""

    def __init__(self) -> None:
        self.last_seq: int | None = None
        self.gaps = 0
        self.missing = 0
        self.resets = 0
        self.duplicates = 0

    def observe(self, seq: int) -> None:
        """Account for the next received ``seq``."""
        last = self.last_seq
        if last is not None:
            if seq > last + 1:
                self.gaps += 1
                self.missing += seq - last - 1
            elif seq == last:
                self.duplicates += 1
                return
            elif seq < last:
                self.resets += 1
                if seq > 0:
                    self.gaps += 1
                    self.missing += seq
        self.last_seq = seq


@dataclass(frozen=True)
class StreamStats:
    """Counters of one stream (rate, state or health) since the subscriber opened."""

    received: int
    gaps: int
    missing: int
    resets: int
    duplicates: int
    undecodable: int
    dropped: int
    callback_errors: int
    last_seq: int | None
    last_error: str | None
    latency: LatencyStats
    non_finite: int = 0
    """Messages delivered with ``StatusFlags.NON_FINITE``: a rate, raw rate or bias
    value NaN or ±inf (rate stream; set by the decoder, never by the daemon)."""


@dataclass(frozen=True)
class SubscriberStats:
    """Per-stream statistics of a :class:`Subscriber`."""

    rate: StreamStats
    state: StreamStats
    health: StreamStats
