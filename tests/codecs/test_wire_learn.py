"""The state message's appended ``learn`` element: round trip, an older decoder that
ignores it (and reads the ``zero`` written as off), and a malformed one named."""

from __future__ import annotations

import math

import msgpack
import pytest

from gyrotherm import DecodeError
from gyrotherm.codecs import _wire_decode
from gyrotherm.codecs._wire import (
    LearnProgress,
    MessageKind,
    StateMessage,
    StatusFlags,
    ZeroStatus,
    encode_state,
)
from gyrotherm.codecs._wire_decode import decode_state

LEARN = LearnProgress(True, math.nan, "learning: need 2 more warm-ups at rest", 1,
                      {"motion": 2}, 3.5, 10.25, math.nan, math.nan, 2)
MSG = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                   StatusFlags.NONE, learn=LEARN)


def test_round_trip_and_layout() -> None:
    a = msgpack.unpackb(encode_state(MSG))
    assert len(a) == 16 and a[13] == {} and a[14] == [0, 0.0, 0.0, 0.0]
    assert a[15][2] == LEARN.status and a[15][4] == {"motion": 2}
    got = decode_state(encode_state(MSG))
    assert got.learn is not None and got.learn.status == LEARN.status
    assert got.learn.warmups_used == 1 and got.learn.need_warmups == 2
    assert math.isnan(got.learn.adopted_time_s) and got.learn.t_max_c == 10.25
    assert got.zero is not None and got.zero.status == ZeroStatus.OFF


def test_a_decoder_from_before_learn_ignores_it(monkeypatch: pytest.MonkeyPatch) -> None:
    appended = dict(_wire_decode._APPENDED)
    appended[MessageKind.STATE] = [f for f in appended[MessageKind.STATE] if f[0] != "learn"]
    monkeypatch.setattr(_wire_decode, "_APPENDED", appended)
    older = decode_state(encode_state(MSG))
    assert older.learn is None and older.bias_dps == MSG.bias_dps


def test_a_malformed_learn_is_named() -> None:
    a = msgpack.unpackb(encode_state(MSG))
    a[15][3] = -1
    with pytest.raises(DecodeError, match=r"learn.warmups_used.*index 15"):
        decode_state(msgpack.packb(a))
    a[15] = [True]
    with pytest.raises(DecodeError, match=r"'learn' \(index 15\).*10 elements"):
        decode_state(msgpack.packb(a))
