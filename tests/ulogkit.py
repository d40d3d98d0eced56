"""A ULog writer byte-exact from the published specification (docs.px4.io, "ULog
File Format"), independent of pyulog and of gyrotherm's reader: builds the test
fixtures ``tests/data/px4_two_gyros.ulg`` and the malformed variants.

Layout: 16-byte header (magic ``ULog\\x01\\x12\\x35``, version, µs timestamp),
then messages of ``uint16 msg_size, uint8 msg_type, payload``: ``B`` flag bits,
``F`` formats, ``I`` info, ``A`` add-logged (multi_id, msg_id, name), ``D`` data
(msg_id, packed fields, little-endian, no padding).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from pathlib import Path

MAGIC = b"ULog\x01\x12\x35"
_TYPES = {"uint64_t": "Q", "uint32_t": "I", "float": "f", "uint8_t": "B"}

GYRO_FIELDS = [("uint64_t", "timestamp"), ("uint64_t", "timestamp_sample"),
               ("uint32_t", "device_id"), ("float", "x"), ("float", "y"), ("float", "z"),
               ("float", "temperature"), ("uint32_t", "error_count")]
ACCEL_FIELDS = GYRO_FIELDS

# The values the fixture is written with (and the test expects back).
GYRO0_DEVICE_ID = 263178  # PX4 docs' worked example: SPI bus 1 address 0x04 devtype 0x04
GYRO1_DEVICE_ID = 2424842
# (timestamp µs, timestamp_sample µs, x, y, z rad/s, temperature °C)
GYRO0 = [
    (1_000_500, 1_000_000, 0.01, -0.02, 0.5, 30.0),
    (1_010_500, 1_010_000, 0.02, -0.02, 0.5, 30.5),
    (1_030_500, 1_030_000, 0.04, -0.02, 0.5, 31.5),  # logged before the next: out of order
    (1_020_500, 1_020_000, 0.03, -0.02, 0.5, 31.0),
    (1_040_500, 1_040_000, 0.05, -0.02, 0.5, 32.0),
    (1_040_600, 1_040_000, 0.99, 0.99, 0.99, 99.0),  # repeated sample time: dropped
]
GYRO1 = [(2_000_000 + 10_000 * k, 2_000_000 + 10_000 * k, math.pi, -math.pi / 2, 0.0,
          45.25 + k) for k in range(4)]
# (timestamp_sample µs, x, y, z m/s²): instance 0 only, at 20 ms steps
ACCEL0 = [(1_000_000, 0.0, 0.0, -9.8), (1_020_000, 0.2, 0.0, -9.8),
          (1_040_000, 0.4, 0.0, -9.6)]


def _msg(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def _format(name: str, fields: Sequence[tuple[str, str]]) -> bytes:
    text = name + ":" + "".join(f"{t} {n};" for t, n in fields)
    return _msg(b"F", text.encode("ascii"))


def _pack(fields: Sequence[tuple[str, str]], values: Sequence[float | int]) -> bytes:
    return struct.pack("<" + "".join(_TYPES[t] for t, _ in fields), *values)


def header_and_definitions(*, with_gyro: bool = True) -> bytes:
    out = MAGIC + struct.pack("<BQ", 1, 0)
    out += _msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    key = b"char[8] sys_name"
    out += _msg(b"I", bytes([len(key)]) + key + b"fixture!")
    if with_gyro:
        out += _format("sensor_gyro", GYRO_FIELDS)
    out += _format("sensor_accel", ACCEL_FIELDS)
    return out


def two_gyros() -> bytes:
    """sensor_gyro instances 0 and 1 (msg ids 0, 1), sensor_accel instance 0 (id 2)."""
    out = header_and_definitions()
    out += _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    out += _msg(b"A", struct.pack("<BH", 1, 1) + b"sensor_gyro")
    out += _msg(b"A", struct.pack("<BH", 0, 2) + b"sensor_accel")
    for ts, tss, x, y, z, temp in GYRO0:
        out += _msg(b"D", struct.pack("<H", 0) + _pack(
            GYRO_FIELDS, [ts, tss, GYRO0_DEVICE_ID, x, y, z, temp, 0]))
    for ts, tss, x, y, z, temp in GYRO1:
        out += _msg(b"D", struct.pack("<H", 1) + _pack(
            GYRO_FIELDS, [ts, tss, GYRO1_DEVICE_ID, x, y, z, temp, 0]))
    for tss, x, y, z in ACCEL0:
        out += _msg(b"D", struct.pack("<H", 2) + _pack(
            ACCEL_FIELDS, [tss + 100, tss, 1, x, y, z, 30.0, 0]))
    return out


def no_gyro() -> bytes:
    """Only sensor_accel logged."""
    out = header_and_definitions(with_gyro=False)
    out += _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_accel")
    for tss, x, y, z in ACCEL0:
        out += _msg(b"D", struct.pack("<H", 0) + _pack(
            ACCEL_FIELDS, [tss, tss, 1, x, y, z, 30.0, 0]))
    return out


def nan_temperature() -> bytes:
    """One sensor_gyro instance whose temperature is NaN throughout."""
    out = header_and_definitions()
    out += _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    for ts, tss, x, y, z, _ in GYRO0[:3]:
        out += _msg(b"D", struct.pack("<H", 0) + _pack(
            GYRO_FIELDS, [ts, tss, GYRO0_DEVICE_ID, x, y, z, math.nan, 0]))
    return out


def no_temperature_field() -> bytes:
    """A sensor_gyro format without the temperature field (as in early PX4 logs)."""
    fields = [f for f in GYRO_FIELDS if f[1] != "temperature"]
    out = MAGIC + struct.pack("<BQ", 1, 0)
    out += _msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    out += _format("sensor_gyro", fields)
    out += _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    for ts, tss, x, y, z, _ in GYRO0[:3]:
        out += _msg(b"D", struct.pack("<H", 0) + _pack(fields, [ts, tss, 1, x, y, z, 0]))
    return out


def write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


if __name__ == "__main__":  # regenerate the committed fixture
    here = Path(__file__).parent / "data"
    write(here / "px4_two_gyros.ulg", two_gyros())
