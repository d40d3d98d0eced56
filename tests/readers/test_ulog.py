"""PX4 ULog reader: the spec-built fixture (tests/ulogkit.py), a real PX4 log, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ulogkit
from gyrotherm import RunFileError
from gyrotherm.readers._ulog import decode_device_id, read_ulog

DATA = Path(__file__).parents[1] / "data"
FIXTURE = DATA / "px4_two_gyros.ulg"
REAL = DATA / "px4_sample_log_small_imu.ulg"


def test_committed_fixture_is_what_the_spec_writer_writes() -> None:
    assert FIXTURE.read_bytes() == ulogkit.two_gyros()


def test_every_gyro_instance_with_values_converted() -> None:
    runs = read_ulog(FIXTURE)
    assert [r.name for r in runs] == ["px4_two_gyros:sensor_gyro0", "px4_two_gyros:sensor_gyro1"]
    g0, g1 = runs
    # sample times (timestamp_sample, µs → s), sorted, the repeated 1 040 000 µs dropped
    np.testing.assert_allclose(g0.time_s, [1.00, 1.01, 1.02, 1.03, 1.04], rtol=0, atol=1e-12)
    np.testing.assert_allclose(g0.temperature_c, [30.0, 30.5, 31.0, 31.5, 32.0])
    # 0.01 rad/s = 0.5729578 °/s; 0.5 rad/s = 28.64789 °/s (float32 in the file)
    np.testing.assert_allclose(g0.rates_dps["x"], [0.5729578, 1.1459156, 1.7188734,
                                                   2.2918312, 2.8647890], rtol=1e-6)
    np.testing.assert_allclose(g0.rates_dps["z"], 28.64789, rtol=1e-6)
    assert g0.metadata["rows_reordered"] == "1"
    assert g0.metadata["rows_duplicate_time_dropped"] == "1"
    assert g0.metadata["device_id"] == "263178"
    assert g0.metadata["device"] == "SPI bus 1 address 0x04 devtype 0x04"
    assert g0.metadata["format"] == "px4-ulog" and g0.metadata["instance"] == "0"
    # π rad/s = 180 °/s, -π/2 = -90 °/s
    np.testing.assert_allclose(g1.rates_dps["x"], 180.0, rtol=1e-6)
    np.testing.assert_allclose(g1.rates_dps["y"], -90.0, rtol=1e-6)
    np.testing.assert_allclose(g1.temperature_c, [45.25, 46.25, 47.25, 48.25])
    assert g1.metadata["instance"] == "1" and g1.metadata["device_id"] == "2424842"
    assert g0.source == str(FIXTURE) and len(g0.sha256) == 64


def test_accelerometer_of_the_same_instance_interpolated_onto_gyro_times() -> None:
    g0, g1 = read_ulog(FIXTURE)
    # accel at 1.00/1.02/1.04 s: x 0/0.2/0.4, z -9.8/-9.8/-9.6 → at the gyro's 1.01, 1.03 s
    np.testing.assert_allclose(g0.extra["accel_x_mps2"], [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-6)
    np.testing.assert_allclose(g0.extra["accel_z_mps2"], [-9.8, -9.8, -9.8, -9.7, -9.6],
                               atol=1e-6)
    assert g0.metadata["accel"] == "sensor_accel 0"
    assert g1.extra == {} and g1.metadata["accel"] == "none"


def test_device_id_decoding_matches_px4_docs_example() -> None:
    assert decode_device_id(263178) == "SPI bus 1 address 0x04 devtype 0x04"
    assert decode_device_id(66826) == "SPI bus 1 address 0x05 devtype 0x01"


def test_real_px4_log() -> None:
    runs = read_ulog(REAL)
    assert [r.metadata["device_id"] for r in runs] == ["2424842", "3670050", "2621474"]
    for r in runs:
        assert len(r) == 6 and np.all(np.diff(r.time_s) > 0)
        assert 21.0 < r.time_s[0] < 22.0  # s since boot
        assert 20.0 < r.temperature_c.min() and r.temperature_c.max() < 50.0
        assert set(r.extra) == {"accel_x_mps2", "accel_y_mps2", "accel_z_mps2"}
        g = np.sqrt(sum(r.extra[k] ** 2 for k in r.extra))
        assert np.all(np.abs(g - 9.81) < 1.5)  # the accelerometer sees gravity
    # first rows as pyulog's ulog2csv prints them for the original sample_log_small.ulg:
    # 21311647 µs, x -0.04130321 rad/s (= -2.366500 °/s), 40.02537 °C; 2nd: 40.07329 °C
    np.testing.assert_allclose(runs[0].time_s[0], 21.311647, rtol=0, atol=1e-9)
    np.testing.assert_allclose(runs[0].rates_dps["x"][0], -0.04130321 * 180 / np.pi, rtol=1e-6)
    np.testing.assert_allclose(runs[0].temperature_c[:2], [40.02537, 40.07329], rtol=1e-6)
    np.testing.assert_allclose(runs[1].temperature_c[0], 28.246023, rtol=1e-6)


def test_truncated_header(tmp_path: Path) -> None:
    bad = ulogkit.write(tmp_path / "cut.ulg", ulogkit.two_gyros()[:10])
    with pytest.raises(RunFileError, match=r"cut\.ulg: not a readable PX4 ULog") as exc:
        read_ulog(bad)
    assert exc.value.__cause__ is not None


def test_not_a_ulog(tmp_path: Path) -> None:
    bad = ulogkit.write(tmp_path / "text.ulg", b"timestamp,x,y,z\n1,2,3,4\n" * 4)
    with pytest.raises(RunFileError, match=r"text\.ulg: not a readable PX4 ULog"):
        read_ulog(bad)


def test_truncated_data_reads_what_is_there(tmp_path: Path) -> None:
    data = ulogkit.two_gyros()
    cut = ulogkit.write(tmp_path / "cut.ulg", data[: len(data) - 30])
    runs = read_ulog(cut)
    assert [len(r) for r in runs] == [5, 4]  # the cut hits the accelerometer's last sample


def test_no_gyro_topic(tmp_path: Path) -> None:
    bad = ulogkit.write(tmp_path / "accel_only.ulg", ulogkit.no_gyro())
    with pytest.raises(RunFileError, match=r"accel_only\.ulg: no 'sensor_gyro' topic logged"):
        read_ulog(bad)


def test_no_temperature(tmp_path: Path) -> None:
    bad = ulogkit.write(tmp_path / "nan.ulg", ulogkit.nan_temperature())
    with pytest.raises(RunFileError,
                       match=r"nan\.ulg: topic 'sensor_gyro' instance 0: no temperature"):
        read_ulog(bad)


def test_no_temperature_field(tmp_path: Path) -> None:
    bad = ulogkit.write(tmp_path / "old.ulg", ulogkit.no_temperature_field())
    with pytest.raises(RunFileError, match=r"old\.ulg: topic 'sensor_gyro' instance 0: missing "
                                           r"field\(s\) \['temperature'\]"):
        read_ulog(bad)
