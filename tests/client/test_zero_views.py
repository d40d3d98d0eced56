"""The boot-time zero where a user sees it: ``gyrotherm listen``'s live line and the JSON
state channel ``gyrotherm record`` writes."""

from __future__ import annotations

import math

from gyrotherm.client._listen import format_line
from gyrotherm.client._stats import LatencyStats, StreamStats
from gyrotherm.codecs._wire import RateMessage, StateMessage, StatusFlags, ZeroState

NAN = math.nan
STATS = StreamStats(10, 0, 0, 0, 0, 0, 0, 0, 9, None, LatencyStats(0, NAN, NAN, NAN, NAN, NAN))
RATE = RateMessage(9, 1.0, 2.0, (0.0, 0.0, 0.0), (0.0125, -0.25, 0.0), (0.0125, -0.25, 0.0),
                   StatusFlags.NONE)


def _state(zero: ZeroState | None, flags: StatusFlags = StatusFlags.NONE) -> StateMessage:
    return StateMessage(1, 1.0, 2.0, 25.0, 0.1, 0.5, 0.01, (0.0, 0.0, 0.0), flags, {}, zero)


def test_zero_done_shows_its_offsets() -> None:
    line = format_line(RATE, _state(ZeroState(2, (0.0125, -0.03125, 0.0))), STATS)
    assert "zero done[+0.0125 -0.0312 +0.0000]" in line


def test_zero_pending_and_failed_and_absent() -> None:
    pending = RateMessage(9, 1.0, 2.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                          StatusFlags.ZERO_PENDING)
    line = format_line(pending, _state(ZeroState(1, (0.0, 0.0, 0.0))), STATS)
    assert "zero pending" in line and "flags=ZERO_PENDING" in line
    assert "zero failed" in format_line(RATE, _state(ZeroState(3, (0.0, 0.0, 0.0))), STATS)
    assert "zero" not in format_line(RATE, _state(None), STATS)


def test_recorded_state_json_carries_the_zero() -> None:
    """``record``'s JSON state channel (MCAP, Foxglove) keeps the zero's status and z."""
    from gyrotherm.client._ros import STATE_SCHEMA, state_json

    doc = state_json(_state(ZeroState(2, (0.0125, -0.03125, NAN))))
    assert doc["zero"] == {"status": "done", "offset_dps": {"x": 0.0125, "y": -0.03125,
                                                           "z": None}}
    assert state_json(_state(None))["zero"] is None
    assert set(doc) <= set(STATE_SCHEMA["properties"])
