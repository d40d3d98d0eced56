"""The state message's ``zero`` (boot-time zero, appended within schema 1): bytes
assembled by hand, older decoders' view, round trips and field errors."""

from __future__ import annotations

import struct

import msgpack
import pytest

from gyrotherm import DecodeError
from gyrotherm.codecs import _wire_decode
from gyrotherm.codecs._wire import MessageKind, StateMessage, StatusFlags, ZeroState, encode_state
from gyrotherm.codecs._wire_decode import decode_state


def f64(x: float) -> bytes:
    return b"\xcb" + struct.pack(">d", x)


MSG = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                   StatusFlags.NONE, {}, ZeroState(2, (0.25, -0.5, 0.125)))
# fixarray(15), kind 2, version 1, seq 3, 10 float64, flags 0, empty fixmap (effects
# written before the zero), fixarray(4) [status 2, 3 float64]
BYTES = (
    b"\x9f\x02\x01\x03"
    + b"".join(f64(x) for x in (10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, 1.0, 2.0, 3.0))
    + b"\x00" + b"\x80" + b"\x94\x02" + f64(0.25) + f64(-0.5) + f64(0.125)
)  # fmt: skip


def test_zero_bytes_by_hand_round_trip() -> None:
    assert encode_state(MSG) == BYTES
    assert decode_state(BYTES) == MSG


def test_a_decoder_from_before_the_zero_ignores_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """The decoder as it was before ``zero`` (appended fields: ``effects`` only) decodes
    today's 15-element message: the empty effects map, the trailing zero ignored."""
    a = msgpack.unpackb(BYTES)
    assert len(a) == 15 and a[13] == {} and a[14][0] == 2
    appended = dict(_wire_decode._APPENDED)
    appended[MessageKind.STATE] = [f for f in appended[MessageKind.STATE] if f[0] == "effects"]
    monkeypatch.setattr(_wire_decode, "_APPENDED", appended)
    older = decode_state(BYTES)
    assert older.zero is None and older.effects == {}
    assert older.bias_dps == MSG.bias_dps and older.flags == MSG.flags


def test_todays_decoder_reads_a_publisher_without_the_zero() -> None:
    a = msgpack.unpackb(BYTES)
    older = decode_state(msgpack.packb(a[:14]))  # a publisher without the zero
    assert older.zero is None and older.effects == {}


def test_no_zero_no_element() -> None:
    plain = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0))
    assert len(msgpack.unpackb(encode_state(plain))) == 13


@pytest.mark.parametrize(("zero", "match"), [
    ([4, 0.0, 0.0, 0.0], r"field 'zero.status' \(index 14\) = 4 is not 0, 1, 2 or 3"),
    ([2, 0.0, 0.0], r"field 'zero' \(index 14\) = \[2, 0.0, 0.0\] is not an array of 4"),
    ([2, 0.0, "a", 0.0], r"field 'zero.offset_dps\[1\]' \(index 14\)"),
])
def test_bad_zero_element_is_named(zero: list[object], match: str) -> None:
    a = msgpack.unpackb(BYTES)
    a[14] = zero
    with pytest.raises(DecodeError, match=match):
        decode_state(msgpack.packb(a))
