"""Wire payloads: hand-built msgpack vectors (from the msgpack spec), round trips, errors."""

from __future__ import annotations

import math
import struct

import msgpack
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm import DecodeError, PublishError
from gyrotherm.codecs._wire import (
    SCHEMA_VERSION,
    U64_MAX,
    CalibrationInfo,
    HealthMessage,
    MessageKind,
    RateMessage,
    StateMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
    encode_rate,
    encode_state,
)
from gyrotherm.codecs._wire_decode import (
    decode_calibration_info,
    decode_health,
    decode_message,
    decode_rate,
    decode_state,
)


def f64(x: float) -> bytes:
    """msgpack float 64: 0xcb + IEEE 754 big-endian."""
    return b"\xcb" + struct.pack(">d", x)


# --------------------------------------------------------------- hand-built vectors

RATE_MSG = RateMessage(
    seq=5,
    sensor_time_s=1.5,
    receive_time_s=1700000000.25,
    rate_dps=(0.5, -0.25, 2.0),
    raw_rate_dps=(0.75, 0.0, 2.125),
    bias_dps=(0.25, 0.25, 0.125),
    flags=StatusFlags.T_CLAMPED | StatusFlags.COUNTER_JUMP,
)
# fixarray(15), kind 1, version 1, seq 5, 11 float64, flags 0x22 (bits 1 and 5)
RATE_BYTES = (
    b"\x9f\x01\x01\x05"
    + b"".join(f64(x) for x in (1.5, 1700000000.25, 0.5, -0.25, 2.0, 0.75, 0.0, 2.125))
    + b"".join(f64(x) for x in (0.25, 0.25, 0.125))
    + b"\x22"
)


def test_rate_vector_matches_spec_bytes() -> None:
    assert encode_rate(RATE_MSG) == RATE_BYTES
    assert len(RATE_BYTES) == 1 + 3 + 11 * 9 + 1
    assert decode_rate(RATE_BYTES) == RATE_MSG


def test_state_vector() -> None:
    # fixarray(13), kind 2, version 1, seq uint64 0xcf (2**40), 10 floats, flags 0x01
    seq = 2**40
    data = (
        b"\x9d\x02\x01\xcf" + struct.pack(">Q", seq)
        + b"".join(f64(x) for x in (10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, 1.0, 2.0, 3.0))
        + b"\x01"
    )  # fmt: skip
    msg = StateMessage(seq, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                       StatusFlags.TEMPERATURE_STALE)  # fmt: skip
    assert decode_state(data) == msg
    assert encode_state(msg) == data


def test_health_vector_with_nil_sensor_time() -> None:
    # fixarray(11): kind 3, v1, seq 7, nil, 12.0, 3.5, 1000 (uint16 0xcd), 998,
    # fixmap(1) {fixstr "decode_error": 2}, flags 8, fixstr "cal-A"
    data = (
        b"\x9b\x03\x01\x07\xc0" + f64(12.0) + f64(3.5)
        + b"\xcd\x03\xe8\xcd\x03\xe6"
        + b"\x81\xacdecode_error\x02"
        + b"\x08\xa5cal-A"
    )  # fmt: skip
    msg = decode_health(data)  # 11 elements: a publisher from before counter_jumps
    assert msg == HealthMessage(7, None, 12.0, 3.5, 1000, 998, {"decode_error": 2},
                                StatusFlags.NO_CALIBRATION, "cal-A")  # fmt: skip
    assert msg.drops["decode_error"] == 2 and msg.counter_jumps == 0
    # today's encoder appends counter_jumps (fixarray(12), positive fixint)
    assert encode_health(msg) == b"\x9c" + data[1:] + b"\x00"
    jumped = HealthMessage(7, None, 12.0, 3.5, 1000, 998, {"decode_error": 2},
                           StatusFlags.NO_CALIBRATION, "cal-A", 3)  # fmt: skip
    assert encode_health(jumped) == b"\x9c" + data[1:] + b"\x03"
    assert decode_health(b"\x9c" + data[1:] + b"\x03") == jumped
    with pytest.raises(DecodeError, match=r"field 'counter_jumps' \(index 11\)"):
        decode_health(b"\x9c" + data[1:] + b"\xff")  # negative fixint -1


def test_calibration_vector() -> None:
    # fixarray(5): kind 4, v1, fixstr "c1", fixmap {"a1": 0.5}, nil
    data = b"\x95\x04\x01\xa2c1\x81\xa2a1" + f64(0.5) + b"\xc0"
    info = decode_calibration_info(data)
    assert info == CalibrationInfo("c1", {"a1": 0.5}, None)
    assert encode_calibration_info(info) == data


def test_flag_bits_are_the_documented_ones() -> None:
    expected = {
        "TEMPERATURE_STALE": 0, "T_CLAMPED": 1, "DELTA_T_CLAMPED": 2, "NO_CALIBRATION": 3,
        "ESTIMATOR_REJECTED": 4, "COUNTER_JUMP": 5, "ESTIMATOR_WARMUP": 6, "RATE_SATURATED": 7,
        "SENSOR_FAULT": 8, "NON_FINITE": 9, "BIAS_INVALID": 10, "T_ON_CLAMPED": 11,
        "ZERO_PENDING": 12, "ZERO_FAILED": 13, "ZERO_UNVERIFIED": 14,
    }  # fmt: skip
    assert {f.name: int(f).bit_length() - 1 for f in StatusFlags if f} == expected
    assert [int(k) for k in MessageKind] == [1, 2, 3, 4]
    assert SCHEMA_VERSION == 1


def test_unknown_flag_bits_are_kept() -> None:
    data = msgpack.packb([1, 1, 0, 0.0, 0.0] + [0.0] * 9 + [(1 << 40) | 1])
    msg = decode_rate(data)
    assert int(msg.flags) == (1 << 40) | 1
    assert StatusFlags.TEMPERATURE_STALE in msg.flags


def test_trailing_fields_are_ignored_within_a_version() -> None:
    assert decode_rate(RATE_BYTES[:1].replace(b"\x9f", b"\xdc\x00\x10") + RATE_BYTES[1:]
                       + b"\xa5extra") == RATE_MSG  # fmt: skip


def test_nan_means_not_available_and_survives() -> None:
    msg = StateMessage(0, 1.0, 2.0, math.nan, math.nan, math.nan, math.nan, (0.0, 0.0, 0.0))
    out = decode_state(encode_state(msg))
    assert math.isnan(out.temperature_c) and math.isnan(out.delta_t_std_c)


def test_integer_floats_from_other_encoders_are_accepted() -> None:
    data = msgpack.packb([1, 1, 3, 1, 2, 1, 2, 3, 4, 5, 6, 0, 0, 0, 0])
    msg = decode_rate(data)
    assert msg.receive_time_s == 2.0 and isinstance(msg.rate_dps[0], float)
    assert msg.raw_rate_dps == (4.0, 5.0, 6.0)


def test_decode_message_dispatches_on_kind() -> None:
    assert decode_message(RATE_BYTES) == RATE_MSG
    health = HealthMessage(1, 2.0, 3.0, 4.0, 5, 6, {}, StatusFlags.NONE, "")
    assert decode_message(encode_health(health)) == health
    with pytest.raises(DecodeError, match=r"'kind' \(index 0\) = 9"):
        decode_message(msgpack.packb([9, 1]))


# --------------------------------------------------------------- errors

RATE_OK = [1, 1, 0, 0.0, 0.0] + [0.0] * 9 + [0]


def _with(index: int, value: object) -> bytes:
    a = list(RATE_OK)
    a[index] = value
    return msgpack.packb(a)


@pytest.mark.parametrize(
    ("payload", "pattern"),
    [
        (b"\xc1", r"rate payload: not valid msgpack \(1 bytes\)"),
        (b"", r"not valid msgpack \(0 bytes\)"),
        (RATE_BYTES[:20], r"not valid msgpack \(20 bytes\)"),
        (RATE_BYTES + b"\x00", r"not valid msgpack"),
        (msgpack.packb({"seq": 1}), r"expected a msgpack array, got dict"),
        (msgpack.packb([1]), r"array has 1 elements"),
        (_with(0, 2), r"field 'kind' \(index 0\) = 2 \(state\) is not 1 \(rate\)"),
        (_with(1, 2), r"field 'version' \(index 1\) = 2 is not the supported version 1"),
        (_with(1, "1"), r"field 'version' \(index 1\) = '1'"),
        (msgpack.packb(RATE_OK[:10]), r"missing field 'raw_rate_dps\[2\]' \(index 10\)"),
        (msgpack.packb(RATE_OK[:-1]), r"missing field 'flags' \(index 14\).*expected 15"),
        (_with(2, -1), r"field 'seq' \(index 2\) = -1 is out of range \[0, 18446744073709551615\]"),
        (_with(2, 1.0), r"field 'seq' \(index 2\) = 1.0 is float, expected uint64"),
        (_with(2, True), r"field 'seq' \(index 2\) = True is bool"),
        (_with(4, math.inf), r"field 'receive_time_s' \(index 4\) = inf is not finite"),
        (_with(3, math.nan), r"field 'sensor_time_s' \(index 3\) = nan is not finite"),
        (_with(9, "x"), r"field 'raw_rate_dps\[1\]' \(index 9\) = 'x' is str, expected float"),
        (_with(12, None), r"field 'bias_dps\[1\]' \(index 12\) = None is NoneType"),
        (_with(14, -3), r"field 'flags' \(index 14\) = -3 is out of range"),
    ],
)
def test_bad_rate_payloads_name_field_and_value(payload: bytes, pattern: str) -> None:
    with pytest.raises(DecodeError, match=pattern):
        decode_rate(payload)


def test_non_bytes_payload() -> None:
    with pytest.raises(DecodeError, match="rate payload: expected bytes, got str"):
        decode_rate("abc")  # type: ignore[arg-type]


def test_bad_health_and_calibration_fields() -> None:
    good = [3, 1, 0, None, 1.0, 1.0, 0, 0, {}, 0, ""]
    bad_drops = list(good)
    bad_drops[8] = {"decode_error": -1}
    with pytest.raises(DecodeError, match=r"'drops\['decode_error'\]' \(index 8\) = -1"):
        decode_health(msgpack.packb(bad_drops))
    bad_id = list(good)
    bad_id[10] = 5
    with pytest.raises(DecodeError, match=r"'calibration_id' \(index 10\) = 5 is int"):
        decode_health(msgpack.packb(bad_id))
    with pytest.raises(DecodeError, match=r"health payload: field 'kind' .* = 1 \(rate\)"):
        decode_health(RATE_BYTES)
    with pytest.raises(DecodeError, match=r"calibration payload: field 'calibration key' \(index"):
        decode_calibration_info(msgpack.packb([4, 1, "c", {b"k": 2}, None]))
    with pytest.raises(DecodeError, match=r"not valid msgpack .*map key"):
        decode_calibration_info(msgpack.packb([4, 1, "c", {1: 2}, None]))
    nested = [4, 1, "c", None, [3, 2]]
    with pytest.raises(DecodeError, match=r"calibration\.health payload: field 'version'"):
        decode_calibration_info(msgpack.packb(nested))


def test_unencodable_message_raises_publish_error() -> None:
    msg = RateMessage(2**64, 0.0, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    with pytest.raises(PublishError, match="rate message: cannot encode"):
        encode_rate(msg)


def test_messages_are_frozen() -> None:
    with pytest.raises(AttributeError):
        RATE_MSG.seq = 3  # type: ignore[misc]
    health = HealthMessage(0, None, 0.0, 0.0, 0, 0, {"a": 1})
    with pytest.raises(TypeError):
        health.drops["a"] = 2  # type: ignore[index]


# --------------------------------------------------------------- round trips

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
values = st.floats(allow_nan=False, width=64)  # ±inf allowed in measurements
vec3 = st.tuples(values, values, values)
u64 = st.integers(0, U64_MAX)
flags = st.integers(0, U64_MAX).map(StatusFlags)


@settings(derandomize=True, max_examples=150, deadline=None, database=None)
@given(u64, finite, finite, vec3, vec3, vec3, flags)
def test_rate_round_trip(seq, t0, t1, r, w, b, fl) -> None:
    msg = RateMessage(seq, t0, t1, r, w, b, fl)
    # the decoder adds NON_FINITE (client side) when a value is ±inf
    finite_values = all(math.isfinite(v) for v in (*r, *w, *b))
    want_flags = fl if finite_values else fl | StatusFlags.NON_FINITE
    assert decode_rate(encode_rate(msg)) == RateMessage(seq, t0, t1, r, w, b, want_flags)


@settings(derandomize=True, max_examples=100, deadline=None, database=None)
@given(u64, finite, finite, values, values, values, values, vec3, flags)
def test_state_round_trip(seq, t0, t1, tc, ts, dt, ds, b, fl) -> None:
    msg = StateMessage(seq, t0, t1, tc, ts, dt, ds, b, fl)
    assert decode_state(encode_state(msg)) == msg


health_st = st.builds(
    HealthMessage,
    u64,
    st.none() | finite,
    finite,
    finite,
    u64,
    u64,
    st.dictionaries(st.text(max_size=20), u64, max_size=5),
    flags,
    st.text(max_size=40),
)


@settings(derandomize=True, max_examples=100, deadline=None, database=None)
@given(health_st)
def test_health_round_trip(msg: HealthMessage) -> None:
    assert decode_health(encode_health(msg)) == msg


json_scalar = st.none() | st.booleans() | st.integers(-(2**63), 2**63 - 1) | finite | st.text()
json_value = st.recursive(
    json_scalar,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(), inner, max_size=4),
    max_leaves=10,
)


@settings(derandomize=True, max_examples=60, deadline=None, database=None)
@given(st.text(max_size=30), st.none() | st.dictionaries(st.text(), json_value, max_size=5),
       st.none() | health_st)  # fmt: skip
def test_calibration_round_trip(cal_id, cal, health) -> None:
    info = CalibrationInfo(cal_id, cal, health)
    assert decode_calibration_info(encode_calibration_info(info)) == info


@settings(derandomize=True, max_examples=200, deadline=None, database=None)
@given(st.binary(max_size=64))
def test_garbage_raises_only_decode_error(data: bytes) -> None:
    decoders = [(decode_rate, RateMessage), (decode_state, StateMessage),
                (decode_health, HealthMessage), (decode_calibration_info, CalibrationInfo)]
    for decode, cls in decoders:
        try:
            out = decode(data)
        except DecodeError as exc:
            assert str(exc).split(" ", 1)[0] in {"rate", "state", "health", "calibration"}
        else:
            assert isinstance(out, cls)  # garbage that happens to be a valid payload


def test_every_flag_is_documented_with_its_bit() -> None:
    """docs/wire-format.md and docs/operations.md list every flag with its bit and value."""
    import re
    from pathlib import Path

    docs = Path(__file__).resolve().parents[2] / "docs"
    wire = (docs / "wire-format.md").read_text(encoding="utf-8")
    ops = (docs / "operations.md").read_text(encoding="utf-8")
    for f in StatusFlags:
        if not f:
            continue
        bit, value = int(f).bit_length() - 1, int(f)
        hexes = {f"{value:#x}", f"{value:#04x}"}  # 0x01 … 0x80 are written with two digits
        assert any(re.search(rf"^\| {bit} \| {h} \| `{f.name}` \|", wire, re.M)
                   for h in hexes), f.name
        assert re.search(rf"^\| {bit} \| {value} \| `{f.name}` \|", ops, re.M), f.name
