"""The state message's ``effects`` (appended within schema 1): the documented byte
vector (docs/wire-format.md), old decoders, round trips and field errors."""

from __future__ import annotations

import math
import re
import struct
from pathlib import Path

import msgpack
import pytest

from gyrotherm import DecodeError
from gyrotherm.codecs import _wire_decode
from gyrotherm.codecs._wire import AxisEffects, StateMessage, StatusFlags, encode_state
from gyrotherm.codecs._wire_decode import decode_message, decode_state

DOC = Path(__file__).resolve().parents[2] / "docs" / "wire-format.md"


def f64(x: float) -> bytes:
    return b"\xcb" + struct.pack(">d", x)


MSG = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                   StatusFlags.T_ON_CLAMPED | StatusFlags.ESTIMATOR_WARMUP,
                   {"x": AxisEffects(31.25, -0.5, -1, 600.0, 0.0125)})
# fixarray(14), kind 2, version 1, seq 3, 10 float64, flags 0x840 as uint16 (0xcd),
# fixmap(1) {fixstr "x": fixarray(5) [f64, f64, negative fixint -1, f64, f64]}
BYTES = (
    b"\x9e\x02\x01\x03"
    + b"".join(f64(x) for x in (10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, 1.0, 2.0, 3.0))
    + b"\xcd\x08\x40"
    + b"\x81\xa1x\x95" + f64(31.25) + f64(-0.5) + b"\xff" + f64(600.0) + f64(0.0125)
)  # fmt: skip


def test_state_vector_with_effects_matches_the_spec_bytes() -> None:
    assert len(BYTES) == 129
    assert encode_state(MSG) == BYTES
    assert decode_state(BYTES) == MSG
    assert decode_message(BYTES) == MSG


def test_the_documented_hex_is_this_vector() -> None:
    text = DOC.read_text(encoding="utf-8")
    m = re.search(r"state-effects-vector:\s*\n```\n([0-9a-f\n]+)```", text)
    assert m, "docs/wire-format.md lacks the state-effects-vector block"
    assert bytes.fromhex(m.group(1).replace("\n", "")) == BYTES


def test_an_old_decoder_ignores_the_appended_effects(monkeypatch: pytest.MonkeyPatch) -> None:
    """A decoder from before ``effects`` knows no appended state field: trailing
    elements are ignored, every other field decodes as before."""
    monkeypatch.setattr(_wire_decode, "_APPENDED", {})
    old = decode_state(BYTES)
    assert old == StateMessage(*[getattr(MSG, f) for f in (
        "seq", "sensor_time_s", "receive_time_s", "temperature_c", "temperature_std_c",
        "delta_t_c", "delta_t_std_c", "bias_dps", "flags")])
    assert old.effects == {}


def test_without_effects_the_message_is_the_13_element_one() -> None:
    plain = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0))
    data = encode_state(plain)
    assert data[0] == 0x9d and decode_state(data) == plain and decode_state(data).effects == {}


def test_nan_effects_survive_a_round_trip() -> None:
    msg = StateMessage(0, 1.0, 2.0, 20.0, 0.1, 0.0, 0.1, (0.0, 0.0, 0.0), StatusFlags.NONE,
                       {a: AxisEffects(math.nan, math.nan, 0, 5.0, math.nan) for a in "xyz"})
    back = decode_state(encode_state(msg))
    assert set(back.effects) == {"x", "y", "z"}
    assert math.isnan(back.effects["y"].structure_temperature_c)
    assert back.effects["z"].t_on_s == 5.0


@pytest.mark.parametrize(("effects", "pattern"), [
    ([1.0], r"field 'effects' \(index 13\) = \[1\.0\] is list, expected map"),
    ({"w": [0.0, 0.0, 0, 0.0, 0.0]}, r"field 'effects key' \(index 13\) = 'w' is not an axis"),
    ({"x": [0.0, 0.0, 0]},
     r"field 'effects\['x'\]' \(index 13\) = \[0\.0, 0\.0, 0\] is not an array of 5"),
    ({"x": [0.0, 0.0, 2, 0.0, 0.0]},
     r"effects\['x'\]\.hysteresis_direction.* = 2 is not -1, 0 or 1"),
    ({"x": [0.0, "hot", 0, 0.0, 0.0]}, r"effects\['x'\]\.hysteresis_h.* is str, expected float"),
])
def test_bad_effects_name_field_and_value(effects: object, pattern: str) -> None:
    data = msgpack.packb([2, 1, 0, 1.0, 2.0, 20.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.0, 0, effects])
    with pytest.raises(DecodeError, match=pattern):
        decode_state(data)
