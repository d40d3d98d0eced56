"""Client library: typed subscriber to a gyrotherm daemon's Zenoh streams.

``Subscriber`` decodes the rate / state / health messages (see
docs/wire-format.md), detects sequence gaps, measures latency and answers
calibration queries; ``listen_main`` is the ``gyrotherm listen`` live view.
"""

from gyrotherm.client._listen import listen_main
from gyrotherm.client._stats import (
    LatencyStats,
    LatencyTracker,
    SequenceTracker,
    StreamStats,
    SubscriberStats,
    percentile,
)
from gyrotherm.client._subscriber import Subscriber

__all__ = [
    "LatencyStats",
    "LatencyTracker",
    "SequenceTracker",
    "StreamStats",
    "Subscriber",
    "SubscriberStats",
    "listen_main",
    "percentile",
]
