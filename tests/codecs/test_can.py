"""CAN frame codecs: CRC-8, shipped DBC layout, decoder checks, encoder, custom DBCs.

Truth comes from outside the code under test: the published CRC catalogue check
values and AUTOSAR test vectors, a bitwise CRC written here from the spec,
frames assembled by hand below, and cantools' own decoder.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import cast

import can
import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm import ConfigError, DecodeError
from gyrotherm.codecs._can import (
    FrameDecoder,
    RateSample,
    Rejection,
    RejectReason,
    TemperatureSample,
)
from gyrotherm.codecs._canenc import FrameEncoder
from gyrotherm.codecs._canmap import DEFAULT_DBC_PATH, SignalMap
from gyrotherm.codecs._crc import CRC8_AUTOSAR, CRC8_SAE_J1850, CRC_ALGORITHMS, crc8_algorithm
from streamkit import USER_DBC, USER_SIGNAL_MAP

SETTINGS = settings(max_examples=100, derandomize=True, database=None, deadline=None)
RATE_ID, TEMP_ID = 0x120, 0x121
RATE_LSB, TEMP_LSB = 0.002, 0.01


def crc8_bitwise(data: bytes, poly: int, init: int = 0xFF, xorout: int = 0xFF) -> int:
    """Reference CRC-8 (MSB first, not reflected), straight from the definition."""
    r = init
    for b in data:
        r ^= b
        for _ in range(8):
            r = ((r << 1) ^ poly) & 0xFF if r & 0x80 else (r << 1) & 0xFF
    return r ^ xorout


def load_can_db(path: Path) -> cantools.database.can.Database:
    db = cantools.database.load_file(str(path))
    assert isinstance(db, cantools.database.can.Database)
    return db


@pytest.fixture(scope="module")
def decoder() -> FrameDecoder:
    return FrameDecoder()


@pytest.fixture(scope="module")
def encoder() -> FrameEncoder:
    return FrameEncoder()


# ---------------------------------------------------------------- CRC-8


def test_crc_check_values_from_catalogue() -> None:
    # CRC RevEng catalogue: CRC-8/SAE-J1850 check=0x4b, CRC-8/AUTOSAR check=0xdf.
    assert CRC8_SAE_J1850.compute(b"123456789") == 0x4B == CRC8_SAE_J1850.check
    assert CRC8_AUTOSAR.compute(b"123456789") == 0xDF == CRC8_AUTOSAR.check
    assert crc8_bitwise(b"123456789", 0x1D) == 0x4B
    assert crc8_bitwise(b"123456789", 0x2F) == 0xDF


@pytest.mark.parametrize(
    ("data", "j1850", "h2f"),
    [  # AUTOSAR SWS CRC Library, tables of Crc_CalculateCRC8 / Crc_CalculateCRC8H2F
        ("00000000", 0x59, 0x12),
        ("F20183", 0x37, 0xC2),
        ("0FAA0055", 0x79, 0xC6),
        ("00FF5511", 0xB8, 0x77),
        ("332255AABBCCDDEEFF", 0xCB, 0x11),
        ("926B55", 0x8C, 0x33),
        ("FFFFFFFF", 0x74, 0x6C),
    ],
)
def test_crc_autosar_vectors(data: str, j1850: int, h2f: int) -> None:
    assert CRC8_SAE_J1850.compute(bytes.fromhex(data)) == j1850
    assert CRC8_AUTOSAR.compute(bytes.fromhex(data)) == h2f


@SETTINGS
@given(st.binary(max_size=64))
def test_crc_table_matches_bitwise_definition(data: bytes) -> None:
    assert CRC8_SAE_J1850.compute(data) == crc8_bitwise(data, 0x1D)
    assert CRC8_AUTOSAR.compute(data) == crc8_bitwise(data, 0x2F)


def test_crc_algorithm_names() -> None:
    assert crc8_algorithm("crc-8/sae-j1850") is CRC8_SAE_J1850
    assert crc8_algorithm("CRC-8/AUTOSAR") is CRC8_AUTOSAR
    assert crc8_algorithm("None") is None
    assert set(CRC_ALGORITHMS) == {"CRC-8/SAE-J1850", "CRC-8/AUTOSAR", "none"}
    with pytest.raises(ConfigError, match=r"'CRC-16'.*CRC-8/SAE-J1850"):
        crc8_algorithm("CRC-16")


# ---------------------------------------------------------------- shipped layout


def test_shipped_dbc_is_the_documented_layout() -> None:
    db = load_can_db(DEFAULT_DBC_PATH)
    rate = db.get_message_by_name("GyroRate")
    temp = db.get_message_by_name("GyroTemperature")
    assert (rate.frame_id, rate.length, rate.is_extended_frame) == (RATE_ID, 8, False)
    assert (temp.frame_id, temp.length, temp.is_extended_frame) == (TEMP_ID, 8, False)
    layout = {
        s.name: (s.start, s.length, s.byte_order, s.is_signed, s.scale, s.minimum, s.maximum)
        for m in (rate, temp)
        for s in m.signals
    }
    le = "little_endian"
    assert layout["RateX"] == (0, 16, le, True, RATE_LSB, -65.534, 65.534)
    assert layout["RateY"][:2] == (16, 16) and layout["RateZ"][:2] == (32, 16)
    assert layout["RateCounter"][:4] == (48, 4, le, False)
    assert layout["RateCrc"][:4] == (56, 8, le, False)
    assert layout["Temperature"] == (0, 16, le, True, TEMP_LSB, -40, 125)
    assert layout["Status"][:2] == (16, 8)
    assert layout["TempCounter"][:2] == (24, 4)
    assert layout["TempCrc"][:2] == (56, 8)


def test_hand_computed_rate_frame(decoder: FrameDecoder) -> None:
    # rate_x = +1.0 °/s  -> 1.0 / 0.002 = 500    = 0x01F4 -> little-endian F4 01
    # rate_y = -2.5 °/s  -> -1250 -> 65536 - 1250 = 64286 = 0xFB1E -> 1E FB
    # rate_z = +0.3 °/s  -> 150   = 0x0096 -> 96 00
    # byte 6: counter 5 in bits 48..51, reserved nibble 0 -> 0x05
    # byte 7: CRC-8/SAE-J1850 of F4 01 1E FB 96 00 05 = 0x28 (checked bitwise below)
    payload = bytes.fromhex("F4011EFB96000528")
    assert crc8_bitwise(payload[:7], 0x1D) == 0x28
    decoder.reset()
    got = decoder.decode_raw(RATE_ID, payload, 12.5)
    assert isinstance(got, RateSample)
    assert got.time_s == 12.5 and got.counter == 5
    assert got.rate_x_dps == pytest.approx(1.0, abs=1e-12)
    assert got.rate_y_dps == pytest.approx(-2.5, abs=1e-12)
    assert got.rate_z_dps == pytest.approx(0.3, abs=1e-12)


def test_hand_computed_temperature_frame(decoder: FrameDecoder) -> None:
    # 25.37 °C / 0.01 = 2537 = 0x09E9 -> E9 09; status 0x00; byte 3: counter 9;
    # bytes 4..6 reserved 0; CRC-8/SAE-J1850 of E9 09 00 09 00 00 00 = 0xD8.
    payload = bytes.fromhex("E909000900000" "0D8")
    assert crc8_bitwise(payload[:7], 0x1D) == 0xD8
    decoder.reset()
    got = decoder.decode(can.Message(
        timestamp=3.0, arbitration_id=TEMP_ID, is_extended_id=False, data=payload
    ))
    assert got == TemperatureSample(3.0, pytest.approx(25.37, abs=1e-12), 0, 9)  # type: ignore[arg-type]
    # negative: -12.5 °C -> -1250 -> 0xFB1E -> 1E FB; byte 2 status 0x0C; byte 3 counter 0;
    # CRC of 1E FB 0C 00 00 00 00 = 0x7C
    payload = bytes.fromhex("1EFB0C000000007C")
    assert crc8_bitwise(payload[:7], 0x1D) == 0x7C
    got = decoder.decode_raw(TEMP_ID, payload, 4.0)
    assert isinstance(got, TemperatureSample)  # 9 -> 0 is a jump; default policy delivers
    assert got.temperature_c == pytest.approx(-12.5) and got.status == 0x0C and got.counter == 0


def test_encoder_reproduces_hand_computed_frame(encoder: FrameEncoder) -> None:
    msg = encoder.encode_rate(RateSample(12.5, 1.0, -2.5, 0.3), counter=5)
    assert bytes(msg.data) == bytes.fromhex("F4011EFB96000528")
    assert (msg.arbitration_id, msg.is_extended_id, msg.timestamp) == (RATE_ID, False, 12.5)


# ---------------------------------------------------------------- rejection reasons


def _rate(enc: FrameEncoder, x: float = 0.0, counter: int | None = None) -> bytes:
    return bytes(enc.encode_rate(RateSample(0.0, x, 0.0, 0.0), counter=counter).data)


def _with_crc(payload: bytes) -> bytes:
    return payload[:7] + bytes([crc8_bitwise(payload[:7], 0x1D)])


def test_unknown_id_is_ignored_and_counted(encoder: FrameEncoder) -> None:
    dec = FrameDecoder()
    got = dec.decode_raw(0x7FF, _rate(encoder), 1.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.UNKNOWN_ID
    assert "0x7FF" in got.detail and got.message is None
    # same id as the rate frame but extended: a different frame
    got = dec.decode_raw(RATE_ID, _rate(encoder), 1.0, is_extended_id=True)
    assert isinstance(got, Rejection) and got.reason == "unknown_id"
    stats = dec.stats()
    assert stats.frames == 2 and stats.events[RejectReason.UNKNOWN_ID] == 2
    assert sum(stats.events.values()) == 2 and set(stats.events) == set(RejectReason)
    with pytest.raises(TypeError):
        stats.events[RejectReason.UNKNOWN_ID] = 0  # type: ignore[index]


@pytest.mark.parametrize("length", [0, 7, 9])
def test_wrong_length(encoder: FrameEncoder, length: int) -> None:
    dec = FrameDecoder()
    got = dec.decode_raw(RATE_ID, (_rate(encoder) * 2)[:length], 1.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.WRONG_LENGTH
    assert f"{length} bytes, expected 8" in got.detail


def test_crc_mismatch_names_signal_and_values(encoder: FrameEncoder) -> None:
    good = _rate(encoder, 1.0, counter=5)  # = F4 01 00 00 00 00 05 CRC
    bad = good[:7] + bytes([good[7] ^ 0xFF])
    got = FrameDecoder().decode_raw(RATE_ID, bad, 1.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.CRC_MISMATCH
    assert "RateCrc" in got.detail and f"0x{good[7]:02X}" in got.detail
    assert "gyro.dbc" in got.detail and got.message == "GyroRate"


def test_invalid_pattern_is_out_of_range() -> None:
    # raw 0x8000 = -32768 -> -65.536 °/s < DBC minimum -65.534: the reserved "invalid" value
    payload = _with_crc(bytes.fromhex("0080" "0000" "0000" "00" "00"))
    got = FrameDecoder().decode_raw(RATE_ID, payload, 1.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.OUT_OF_RANGE
    assert "'RateX' is -65.536" in got.detail and "65.534" in got.detail
    # temperature 126.00 °C -> 12600 = 0x3138 -> 38 31 > maximum 125
    got = FrameDecoder().decode_raw(TEMP_ID, _with_crc(bytes.fromhex("3831000000000000")), 1.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.OUT_OF_RANGE
    assert "'Temperature' is 126" in got.detail


def test_decode_error_for_non_payload_and_non_messages() -> None:
    dec = FrameDecoder()
    for bad in (
        dec.decode_raw(RATE_ID, "not bytes", 1.0),  # type: ignore[arg-type]
        dec.decode_raw(RATE_ID, [1, 2, 300, 4, 5, 6, 7, 8], 1.0),  # type: ignore[arg-type]
        dec.decode(
            can.Message(arbitration_id=RATE_ID, is_extended_id=False, is_remote_frame=True, dlc=8)
        ),
        dec.decode(can.Message(is_error_frame=True)),
        dec.decode(None),
        dec.decode_raw(None, bytes(8), 1.0),  # type: ignore[arg-type]
    ):
        assert isinstance(bad, Rejection) and bad.reason is RejectReason.DECODE_ERROR
    assert dec.stats().events[RejectReason.DECODE_ERROR] == 6


def test_counter_sequence_wraps_and_jumps_are_counted(encoder: FrameEncoder) -> None:
    dec = FrameDecoder()
    frames = [_rate(encoder, counter=c % 16) for c in range(20)]  # 0..15, 0..3: no jump
    assert all(isinstance(dec.decode_raw(RATE_ID, f, 0.0), RateSample) for f in frames)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 0
    # skip 4 -> 5: jump, delivered (default policy); 5 again: repeat is a jump too
    for c in (5, 5, 6):
        got = dec.decode_raw(RATE_ID, _rate(encoder, counter=c), 0.0)
        assert isinstance(got, RateSample) and got.counter == c
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 2
    assert dec.stats().rate_samples == 23
    # the temperature frame keeps its own counter state: its first frame is no jump
    t = bytes(encoder.encode_temperature(TemperatureSample(0.0, 20.0), counter=11).data)
    assert isinstance(dec.decode_raw(TEMP_ID, t, 0.0), TemperatureSample)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 2
    dec.reset()  # forget state: any counter is accepted next
    assert isinstance(dec.decode_raw(RATE_ID, _rate(encoder, counter=0), 0.0), RateSample)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 2


def test_counter_jump_reject_policy_and_crc_failure_breaks_sequence(
    encoder: FrameEncoder,
) -> None:
    dec = FrameDecoder(on_counter_jump="reject")
    assert isinstance(dec.decode_raw(RATE_ID, _rate(encoder, counter=1), 0.0), RateSample)
    corrupt = bytearray(_rate(encoder, counter=2))
    corrupt[0] ^= 0x01
    got = dec.decode_raw(RATE_ID, bytes(corrupt), 0.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.CRC_MISMATCH
    # frame 2 was lost, so 3 follows 1: a jump, rejected under this policy
    got = dec.decode_raw(RATE_ID, _rate(encoder, counter=3), 0.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.COUNTER_JUMP
    assert "'RateCounter' is 3, expected 2" in got.detail
    # the state moved on: 4 is in sequence
    assert isinstance(dec.decode_raw(RATE_ID, _rate(encoder, counter=4), 0.0), RateSample)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 1
    with pytest.raises(ConfigError, match="on_counter_jump"):
        FrameDecoder(on_counter_jump="drop")  # type: ignore[arg-type]


def test_can_filters_pass_exactly_the_mapped_frames(decoder: FrameDecoder) -> None:
    assert decoder.can_filters() == [
        {"can_id": RATE_ID, "can_mask": 0x7FF, "extended": False},
        {"can_id": TEMP_ID, "can_mask": 0x7FF, "extended": False},
    ]


# ---------------------------------------------------------------- encoder


def test_encoder_rolls_counter_and_fills_crc() -> None:
    enc, dec = FrameEncoder(), FrameDecoder()
    msgs = [enc.encode(RateSample(i * 0.01, 0.5, -0.5, 0.0)) for i in range(17)]
    counters = [m.data[6] & 0x0F for m in msgs]
    assert counters == [*range(16), 0]
    for m in msgs:
        assert m.data[7] == crc8_bitwise(bytes(m.data[:7]), 0x1D)
        assert isinstance(dec.decode(m), RateSample)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 0
    t = enc.encode(TemperatureSample(1.0, 30.0, status=0xA5))
    assert t.arbitration_id == TEMP_ID and t.data[2] == 0xA5 and t.data[3] == 0
    enc.reset()
    assert enc.encode(RateSample(0.0, 0.0, 0.0, 0.0)).data[6] == 0


def test_encoder_range_errors_and_saturation(encoder: FrameEncoder) -> None:
    with pytest.raises(DecodeError, match=r"'RateY'.*70 deg/s.*\[-65.534, 65.534\]"):
        encoder.encode_rate(RateSample(0.0, 0.0, 70.0, 0.0))
    with pytest.raises(DecodeError, match=r"'Temperature'.*-41 degC"):
        encoder.encode_temperature(TemperatureSample(0.0, -41.0))
    with pytest.raises(DecodeError, match="NaN"):
        encoder.encode_rate(RateSample(0.0, math.nan, 0.0, 0.0), saturate=True)
    with pytest.raises(DecodeError, match="'Status'"):
        encoder.encode_temperature(TemperatureSample(0.0, 20.0, status=256), saturate=True)
    with pytest.raises(DecodeError, match="counter 16"):
        encoder.encode_rate(RateSample(0.0, 0.0, 0.0, 0.0), counter=16)
    msg = encoder.encode_rate(RateSample(0.0, 70.0, -math.inf, 0.0), saturate=True)
    got = FrameDecoder().decode(msg)
    assert isinstance(got, RateSample)
    assert got.rate_x_dps == pytest.approx(65.534) and got.rate_y_dps == pytest.approx(-65.534)


# ---------------------------------------------------------------- configuration errors


def test_config_errors_name_file_message_and_signal(tmp_path: Path) -> None:
    missing = tmp_path / "nope.dbc"
    with pytest.raises(ConfigError, match=r"nope\.dbc"):
        FrameDecoder(missing)
    m = SignalMap.default()
    bad_msg = SignalMap(**{**m.__dict__, "rate_message": "Gyro"})
    with pytest.raises(ConfigError, match=r"gyro\.dbc: no message 'Gyro'.*GyroRate"):
        FrameDecoder(signal_map=bad_msg)
    bad_sig = SignalMap(**{**m.__dict__, "temperature_signal": "TempX"})
    with pytest.raises(ConfigError, match=r"gyro\.dbc: message 'GyroTemperature' has no signal "
                                          r"'TempX' \(for temperature\)"):
        FrameEncoder(signal_map=bad_sig)
    # the counter as CRC: 4 bits, not a byte
    not_byte = SignalMap(**{**m.__dict__, "rate_crc_signal": "RateCounter"})
    with pytest.raises(ConfigError, match=r"'RateCounter' \(CRC\) must be 8 bits"):
        FrameDecoder(signal_map=not_byte)
    with pytest.raises(ConfigError, match="no CRC signal"):
        SignalMap(**{**m.__dict__, "rate_crc_signal": None, "temperature_crc_signal": None})
    with pytest.raises(ConfigError, match="must differ"):
        SignalMap(**{**m.__dict__, "temperature_message": "GyroRate"})
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['rate_w_signal'\]"):
        SignalMap.from_dict({**m.__dict__, "rate_w_signal": "W"}, source="gyrotherm.toml [can]")
    assert SignalMap.from_dict(dict(m.__dict__)) == m


# ---------------------------------------------------------------- a user's own DBC

CUSTOM_DBC, CUSTOM_MAP = USER_DBC, USER_SIGNAL_MAP
CUSTOM_RATE_ID = 0x18FF1001  # 2566852609 - 2**31: extended


@pytest.fixture(scope="module")
def custom_dbc(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("dbc") / "imu.dbc"
    path.write_text(CUSTOM_DBC)
    return path


@pytest.mark.parametrize("engine", ["compiled", "cantools"])
def test_custom_big_endian_dbc_without_counter_or_crc(custom_dbc: Path, engine: str) -> None:
    dec = FrameDecoder(custom_dbc, CUSTOM_MAP, engine=engine)  # type: ignore[arg-type]
    # Motorola: WX (MSB at bit 7, 12 bits) = byte 0 + high nibble of byte 1;
    # WY (MSB at bit 11) = low nibble of byte 1 + byte 2; WZ = bytes 3..4, offset 2.
    # WX = 1.0 / 0.05 = 20 = 0x014; WY = -0.5 / 0.05 = -10 = 0xFF6 (12-bit two's complement);
    # WZ = (3.0 - 2) / 0.01 = 100 = 0x0064  ->  01 | 4F | F6 | 00 64 | 00
    got = dec.decode_raw(CUSTOM_RATE_ID, bytes.fromhex("014FF6006400"), 7.0, is_extended_id=True)
    assert isinstance(got, RateSample) and got.counter is None
    assert (got.rate_x_dps, got.rate_y_dps, got.rate_z_dps) == pytest.approx((1.0, -0.5, 3.0))
    t = dec.decode_raw(0x3A0, struct.pack("<f", 36.5), 7.0)
    assert t == TemperatureSample(7.0, 36.5, None, None)
    nan = dec.decode_raw(0x3A0, struct.pack("<f", math.nan), 7.0)
    assert isinstance(nan, Rejection) and nan.reason is RejectReason.OUT_OF_RANGE
    # WX raw 0x800 = -2048 -> -102.4 < -100
    low = dec.decode_raw(CUSTOM_RATE_ID, bytes.fromhex("800000006400"), 7.0, is_extended_id=True)
    assert isinstance(low, Rejection) and low.reason is RejectReason.OUT_OF_RANGE
    assert dec.decode_raw(CUSTOM_RATE_ID, bytes(6), 7.0).reason == "unknown_id"  # type: ignore[union-attr]
    msg = FrameEncoder(custom_dbc, CUSTOM_MAP).encode_rate(RateSample(7.0, 1.0, -0.5, 3.0))
    assert bytes(msg.data) == bytes.fromhex("014FF6006400") and msg.is_extended_id


# ---------------------------------------------------------------- properties

rates = st.floats(-65.534, 65.534)
temps = st.floats(-40.0, 125.0)


@SETTINGS
@given(rates, rates, rates, temps, st.integers(0, 255), st.floats(0, 1e9))
def test_round_trip_within_half_lsb(
    encoder: FrameEncoder, x: float, y: float, z: float, t: float, status: int, time_s: float
) -> None:
    for engine in ("compiled", "cantools"):
        dec = FrameDecoder(engine=engine)
        r = dec.decode(encoder.encode_rate(RateSample(time_s, x, y, z)))
        assert isinstance(r, RateSample) and r.time_s == time_s
        for got, want in ((r.rate_x_dps, x), (r.rate_y_dps, y), (r.rate_z_dps, z)):
            assert abs(got - want) <= RATE_LSB / 2 + 1e-12
        s = dec.decode(encoder.encode_temperature(TemperatureSample(time_s, t, status)))
        assert isinstance(s, TemperatureSample) and s.status == status
        assert abs(s.temperature_c - t) <= TEMP_LSB / 2 + 1e-12


@SETTINGS
@given(rates, rates, rates, temps, st.integers(0, 63))
def test_single_bit_corruption_is_detected(
    encoder: FrameEncoder, x: float, y: float, z: float, t: float, bit: int
) -> None:
    for msg in (encoder.encode_rate(RateSample(0.0, x, y, z)),
                encoder.encode_temperature(TemperatureSample(0.0, t))):
        data = bytearray(msg.data)
        data[bit // 8] ^= 1 << (bit % 8)
        got = FrameDecoder().decode_raw(msg.arbitration_id, bytes(data), 0.0)
        assert isinstance(got, Rejection) and got.reason is RejectReason.CRC_MISMATCH


@SETTINGS
@given(st.integers(48, 51), st.integers(0, 15))
def test_counter_bit_flip_without_crc_is_flagged(bit: int, start: int) -> None:
    m = SignalMap.default()
    no_crc = SignalMap(**{**m.__dict__, "rate_crc_signal": None,
                          "temperature_crc_signal": None, "crc_algorithm": "none"})
    enc, dec = FrameEncoder(signal_map=no_crc), FrameDecoder(signal_map=no_crc)
    first = enc.encode_rate(RateSample(0.0, 1.0, 2.0, 3.0), counter=start)
    second = bytearray(enc.encode_rate(RateSample(0.0, 1.0, 2.0, 3.0)).data)
    second[bit // 8] ^= 1 << (bit % 8)  # a counter bit (48..51)
    assert isinstance(dec.decode(first), RateSample)
    dec.decode_raw(RATE_ID, bytes(second), 0.0)
    assert dec.stats().events[RejectReason.COUNTER_JUMP] == 1


@SETTINGS
@given(st.sampled_from([RATE_ID, TEMP_ID]), st.binary(max_size=64).filter(lambda b: len(b) != 8))
def test_truncated_or_extended_payload_is_wrong_length(frame_id: int, payload: bytes) -> None:
    got = FrameDecoder().decode_raw(frame_id, payload, 0.0)
    assert isinstance(got, Rejection) and got.reason is RejectReason.WRONG_LENGTH


@SETTINGS
@given(
    st.one_of(st.integers(0, 0x1FFFFFFF), st.sampled_from([RATE_ID, TEMP_ID])),
    st.booleans(),
    st.one_of(st.binary(max_size=64), st.binary(min_size=8, max_size=8)),
    st.floats(allow_nan=True, allow_infinity=True),
)
def test_garbage_never_raises(frame_id: int, extended: bool, payload: bytes, t: float) -> None:
    for engine in ("compiled", "cantools"):
        dec = FrameDecoder(engine=engine)
        got = dec.decode_raw(frame_id, payload, t, is_extended_id=extended)
        assert isinstance(got, RateSample | TemperatureSample | Rejection)
        fixed = _with_crc(payload) if len(payload) == 8 else payload
        got = dec.decode_raw(frame_id, fixed, t, is_extended_id=extended)
        assert isinstance(got, RateSample | TemperatureSample | Rejection)


@SETTINGS
@given(st.lists(st.tuples(st.sampled_from([RATE_ID, TEMP_ID]), st.binary(min_size=8, max_size=8)),
                min_size=1, max_size=10))
def test_compiled_engine_equals_cantools_engine(frames: list[tuple[int, bytes]]) -> None:
    compiled, reference = FrameDecoder(engine="compiled"), FrameDecoder(engine="cantools")
    for frame_id, payload in frames:
        fixed = _with_crc(payload)
        want = reference.decode_raw(frame_id, fixed, 1.0)
        assert compiled.decode_raw(frame_id, fixed, 1.0) == want
    assert compiled.stats() == reference.stats()


@SETTINGS
@given(st.binary(min_size=6, max_size=6))
def test_custom_compiled_engine_equals_cantools_decode(custom_dbc: Path, payload: bytes) -> None:
    dec, db = _custom_pair(custom_dbc)
    got = dec.decode_raw(CUSTOM_RATE_ID, payload, 0.0, is_extended_id=True)
    want = cast(dict[str, float], db.get_message_by_name("ImuRates").decode_simple(payload))
    in_range = all(-100 <= want[s] <= 100 for s in ("WX", "WY")) and -300 <= want["WZ"] <= 300
    if in_range:
        assert isinstance(got, RateSample)
        assert (got.rate_x_dps, got.rate_y_dps, got.rate_z_dps) == pytest.approx(
            (want["WX"], want["WY"], want["WZ"]), abs=1e-12)
    else:
        assert isinstance(got, Rejection) and got.reason is RejectReason.OUT_OF_RANGE


_CUSTOM: dict[Path, tuple[FrameDecoder, cantools.database.can.Database]] = {}


def _custom_pair(path: Path) -> tuple[FrameDecoder, cantools.database.can.Database]:
    if path not in _CUSTOM:
        _CUSTOM[path] = (FrameDecoder(path, CUSTOM_MAP, engine="compiled"), load_can_db(path))
    return _CUSTOM[path]
