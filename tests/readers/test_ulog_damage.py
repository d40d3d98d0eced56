"""ULogs as real boards leave them: one IMU whose temperature is NaN throughout (a
sensor without one) beside a good one, and a log cut inside a message. Written
byte-exact from the ULog specification (tests/ulogkit.py), so the cut point and the
bad instance are known here, not taken from the reader."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest

import ulogkit
from gyrotherm._errors import RunFileError
from gyrotherm.readers._ulog import bytes_cut_at_end, read_ulog


def _one_good_one_nan() -> bytes:
    out = ulogkit.header_and_definitions()
    out += ulogkit._msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    out += ulogkit._msg(b"A", struct.pack("<BH", 1, 1) + b"sensor_gyro")
    for ts, tss, x, y, z, _ in ulogkit.GYRO1:
        out += ulogkit._msg(b"D", struct.pack("<H", 0) + ulogkit._pack(
            ulogkit.GYRO_FIELDS, [ts, tss, ulogkit.GYRO0_DEVICE_ID, x, y, z, math.nan, 0]))
    for ts, tss, x, y, z, temp in ulogkit.GYRO1:
        out += ulogkit._msg(b"D", struct.pack("<H", 1) + ulogkit._pack(
            ulogkit.GYRO_FIELDS, [ts, tss, ulogkit.GYRO1_DEVICE_ID, x, y, z, temp, 0]))
    return out


def test_an_imu_without_temperature_is_skipped_with_a_note(tmp_path: Path) -> None:
    path = ulogkit.write(tmp_path / "board.ulg", _one_good_one_nan())
    (run,) = read_ulog(path)
    assert run.metadata["device_id"] == str(ulogkit.GYRO1_DEVICE_ID)
    np.testing.assert_array_equal(run.temperature_c, [t[5] for t in ulogkit.GYRO1])
    assert run.metadata["instances_skipped"] == (
        "topic 'sensor_gyro' instance 0: no temperature in 4 sample(s)")


def test_every_imu_bad_is_still_refused(tmp_path: Path) -> None:
    path = ulogkit.write(tmp_path / "nan.ulg", ulogkit.nan_temperature())
    with pytest.raises(RunFileError, match=r"nan\.ulg: topic 'sensor_gyro' instance 0: no "
                                           r"temperature"):
        read_ulog(path)


@pytest.mark.parametrize("partial", [1, 2, 5, 20])
def test_a_log_cut_inside_a_message_is_reported(tmp_path: Path, partial: int) -> None:
    whole = ulogkit.two_gyros()
    extra = ulogkit._msg(b"D", struct.pack("<H", 1) + ulogkit._pack(
        ulogkit.GYRO_FIELDS, [3_000_000, 3_000_000, ulogkit.GYRO1_DEVICE_ID, 0, 0, 0, 50, 0]))
    assert len(extra) > 20
    clean = ulogkit.write(tmp_path / "clean.ulg", whole)
    cut = ulogkit.write(tmp_path / "cut.ulg", whole + extra[:partial])
    assert bytes_cut_at_end(clean) == 0
    assert bytes_cut_at_end(cut) == partial
    runs = read_ulog(cut)
    assert {r.metadata["bytes_cut_at_end"] for r in runs} == {str(partial)}
    assert {r.metadata["file_corruption"] for r in runs} == {"true"}
    assert [len(r) for r in runs] == [len(r) for r in read_ulog(clean)]
