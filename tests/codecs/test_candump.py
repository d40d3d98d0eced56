"""candump -l logs: parse, format, round trip, errors naming file and line, and decoding.

Expected values are read off the can-utils log format by hand (see the lines).
"""

from __future__ import annotations

from pathlib import Path

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm import DecodeError
from gyrotherm.codecs._can import FrameDecoder, RateSample, RejectReason, TemperatureSample
from gyrotherm.codecs._candump import (
    format_candump_line,
    iter_candump,
    parse_candump_line,
    read_candump,
    write_candump,
)
from gyrotherm.codecs._canenc import FrameEncoder

SETTINGS = settings(max_examples=100, derandomize=True, database=None, deadline=None)


def test_parse_the_documented_example() -> None:
    msg = parse_candump_line("(1700000000.123456) can0 123#DEADBEEF\n")
    assert msg.timestamp == pytest.approx(1700000000.123456, abs=1e-7)
    assert msg.channel == "can0"
    assert (msg.arbitration_id, msg.is_extended_id, msg.dlc) == (0x123, False, 4)
    assert bytes(msg.data) == b"\xde\xad\xbe\xef"
    assert not (msg.is_fd or msg.is_remote_frame or msg.is_error_frame)


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        # 8 hex digits: extended id; empty data
        ("(0000000001.000000) vcan0 1ABCDEF0#", dict(arbitration_id=0x1ABCDEF0,
                                                     is_extended_id=True, dlc=0)),
        # remote frame with requested length 5
        ("(1.5) can1 7FF#R5", dict(arbitration_id=0x7FF, is_remote_frame=True, dlc=5)),
        # CAN FD, flags 3 = BRS | ESI, 12 data bytes
        ("(2.0) can0 120##3" + "AB" * 12, dict(is_fd=True, bitrate_switch=True,
                                              error_state_indicator=True, dlc=12)),
        # error frame: CAN_ERR_FLAG 0x20000000 | class 0x80 (bus error)
        ("(3.0) can0 20000080#0000000000000000", dict(is_error_frame=True, arbitration_id=0x80)),
        # '.' separators, python-can's trailing direction flag
        ("(4.0) can0 121#11.22.33 R", dict(arbitration_id=0x121, dlc=3)),
    ],
)
def test_parse_variants(line: str, expected: dict[str, object]) -> None:
    msg = parse_candump_line(line)
    for attr, value in expected.items():
        assert getattr(msg, attr) == value, attr


@pytest.mark.parametrize(
    ("line", "problem"),
    [
        ("garbage", "expected '("),
        ("(1.0) can0 1234#00", "3 (standard) or 8 (extended) hex digits"),
        ("(1.0) can0 800#00", "exceeds 0x7FF"),
        ("(1.0) can0 123#0", "odd number of hex digits"),
        ("(1.0) can0 123#GG", "not hex"),
        ("(1.0) can0 123#001122334455667788", "at most 8 allowed"),
        ("(1.0) can0 123##0" + "00" * 9, "not a valid FD length"),
        ("(1.0) can0 123#R9", "not 0..8"),
        ("1.0 can0 123#00", "expected '("),
    ],
)
def test_bad_lines_name_source_and_line(line: str, problem: str) -> None:
    with pytest.raises(DecodeError, match=r"^log\.txt:42: ") as info:
        parse_candump_line(line, source="log.txt", line_no=42)
    assert problem in str(info.value) and repr(line) in str(info.value)
    assert isinstance(info.value.__cause__, ValueError)


def test_read_file_reports_line_number(tmp_path: Path) -> None:
    path = tmp_path / "bad.log"
    path.write_text("(1.000000) can0 120#00\n\n(2.000000) can0 120#zz\n")
    it = read_candump(path)
    assert next(it).arbitration_id == 0x120
    with pytest.raises(DecodeError, match=r"bad\.log:3: data is not hex"):
        next(it)
    with pytest.raises(DecodeError, match=r"missing\.log: cannot open"):
        list(read_candump(tmp_path / "missing.log"))


def test_format_is_candump_l() -> None:
    msg = can.Message(timestamp=1.5, arbitration_id=0x120, is_extended_id=False,
                      data=bytes.fromhex("f4011efb96000528"))
    assert format_candump_line(msg) == "(0000000001.500000) can0 120#F4011EFB96000528"
    ext = can.Message(timestamp=1700000000.000001, arbitration_id=0x18FF1001, channel="vcan3",
                      data=b"")
    assert format_candump_line(ext) == "(1700000000.000001) vcan3 18FF1001#"
    rtr = can.Message(timestamp=0.0, arbitration_id=0x7, is_extended_id=False,
                      is_remote_frame=True, dlc=2, channel=1)
    assert format_candump_line(rtr) == "(0000000000.000000) can1 007#R2"
    with pytest.raises(DecodeError, match="negative"):
        format_candump_line(can.Message(timestamp=-1.0))


def test_write_read_round_trip_of_encoded_gyro_frames(tmp_path: Path) -> None:
    enc = FrameEncoder()
    msgs = []
    for i in range(40):
        t = 1700000000.0 + i * 0.005
        msgs.append(enc.encode_rate(RateSample(t, 0.01 * i, -0.02 * i, 1.0)))
        if i % 10 == 0:
            msgs.append(enc.encode_temperature(TemperatureSample(t, 20.0 + i * 0.1, status=0)))
    msgs.insert(3, can.Message(timestamp=1700000000.011, arbitration_id=0x7DF,
                               is_extended_id=False, data=b"\x02\x01\x00"))
    path = tmp_path / "gyro.log"
    assert write_candump(path, msgs) == len(msgs)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("(1700000000.000000) can0 120#")
    back = list(read_candump(path))
    assert [bytes(m.data) for m in back] == [bytes(m.data) for m in msgs]
    assert [m.timestamp for m in back] == pytest.approx([m.timestamp for m in msgs], abs=1e-6)
    dec = FrameDecoder()
    results = [dec.decode(m) for m in back]
    rates = [r for r in results if isinstance(r, RateSample)]
    temps = [r for r in results if isinstance(r, TemperatureSample)]
    assert len(rates) == 40 and len(temps) == 4
    assert rates[39].rate_y_dps == pytest.approx(-0.78, abs=0.001)
    assert temps[3].temperature_c == pytest.approx(23.0, abs=0.005)
    stats = dec.stats()
    assert stats.events[RejectReason.UNKNOWN_ID] == 1
    assert stats.events[RejectReason.COUNTER_JUMP] == 0


@SETTINGS
@given(
    st.integers(0, 2**40),
    st.booleans(),
    st.integers(0, 0x1FFFFFFF),
    st.binary(max_size=8),
    st.sampled_from(["can0", "vcan12", "slcan0"]),
)
def test_format_parse_round_trip(us: int, ext: bool, ident: int, data: bytes, ch: str) -> None:
    ident = ident if ext else ident & 0x7FF
    msg = can.Message(timestamp=us / 1e6, arbitration_id=ident, is_extended_id=ext,
                      data=data, channel=ch)
    line = format_candump_line(msg)
    back = parse_candump_line(line)
    assert (back.arbitration_id, back.is_extended_id, bytes(back.data), back.channel) == (
        ident, ext, data, ch)
    assert round(back.timestamp * 1e6) == us
    assert format_candump_line(back) == line


@SETTINGS
@given(st.one_of(
    st.text(max_size=60),
    # near-valid lines reach the frame parser
    st.from_regex(r"\(\d{1,3}\.\d{1,6}\) can0 [0-9A-FR]{1,9}#{1,2}[0-9A-FR_.#]{0,40}",
                  fullmatch=True),
))
def test_garbage_lines_raise_only_decode_error(text: str) -> None:
    try:
        msgs = list(iter_candump([text], source="fuzz"))
    except DecodeError as exc:
        assert str(exc).startswith("fuzz:1: ")
    else:
        assert len(msgs) == (1 if text.strip() else 0)
        for msg in msgs:
            assert parse_candump_line(format_candump_line(msg)).arbitration_id == msg.arbitration_id
