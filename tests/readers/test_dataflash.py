"""ArduPilot DataFlash reader: logs written with pymavlink's writer code
(tests/dataflashkit.py), ArduPilot 3.x style, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dataflashkit
from gyrotherm import RunFileError
from gyrotherm.readers._dataflash import read_dataflash

FIXTURE = Path(__file__).parents[1] / "data" / "ardupilot_two_imus.bin"


def test_committed_fixture_is_what_pymavlink_writes() -> None:
    assert FIXTURE.read_bytes() == dataflashkit.two_imus()


def test_each_imu_instance_with_values_converted() -> None:
    i0, i1 = read_dataflash(FIXTURE)
    assert (i0.name, i1.name) == ("ardupilot_two_imus:IMU[0]", "ardupilot_two_imus:IMU[1]")
    # TimeUS µs → s; the repeated 5 002 500 µs sample dropped (first kept)
    np.testing.assert_allclose(i0.time_s, [5.0, 5.0025, 5.005], rtol=0, atol=1e-12)
    np.testing.assert_allclose(i0.temperature_c, [35.0, 35.125, 35.25])
    # 0.01 rad/s = 0.5729578 °/s, -0.5 rad/s = -28.64789 °/s
    np.testing.assert_allclose(i0.rates_dps["x"], [0.5729578, 1.1459156, 1.7188734], rtol=1e-6)
    np.testing.assert_allclose(i0.rates_dps["z"], -28.64789, rtol=1e-6)
    np.testing.assert_allclose(i0.extra["accel_z_mps2"], -9.81, rtol=1e-6)
    assert i0.metadata["rows_duplicate_time_dropped"] == "1"
    assert i0.metadata["device_id"] == "IMU[0]" and i0.metadata["instance"] == "0"
    assert i0.metadata["format"] == "ardupilot-dataflash"
    np.testing.assert_allclose(i1.time_s, [5.0001, 5.0026], rtol=0, atol=1e-12)
    np.testing.assert_allclose(i1.rates_dps["x"], 180.0, rtol=1e-6)  # π rad/s
    np.testing.assert_allclose(i1.temperature_c, [50.5, 50.75])
    np.testing.assert_allclose(i1.extra["accel_y_mps2"], 0.2, rtol=1e-6)
    assert i1.metadata["device_id"] == "IMU[1]" and i1.source == str(FIXTURE)


def test_numpy_decode_agrees_with_pymavlinks_own_messages() -> None:
    from pymavlink.DFReader import DFReader_binary

    log = DFReader_binary(str(FIXTURE))
    by_instance: dict[int, list[tuple[float, float, float]]] = {}
    while (m := log.recv_match(type="IMU")) is not None:
        by_instance.setdefault(m.I, []).append((m.TimeUS * 1e-6, m.T, m.GyrX))
    for run in read_dataflash(FIXTURE):
        expected = sorted(dict((t, (t, T, g)) for t, T, g in reversed(
            by_instance[int(run.metadata["instance"])])).values())
        got = list(zip(run.time_s, run.temperature_c, run.rates_dps["x"] / (180 / np.pi),
                       strict=True))
        np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_legacy_imu_imu2_messages(tmp_path: Path) -> None:
    p = tmp_path / "old.bin"
    p.write_bytes(dataflashkit.legacy())
    i0, i1 = read_dataflash(p)
    assert (i0.metadata["message"], i1.metadata["message"]) == ("IMU", "IMU2")
    assert i1.metadata["device_id"] == "IMU[1]"
    np.testing.assert_allclose(i0.temperature_c, [35.0, 35.125])
    np.testing.assert_allclose(i1.temperature_c, [50.5, 50.75])


def test_truncated_log_reads_whole_messages(tmp_path: Path) -> None:
    data = dataflashkit.two_imus()
    p = tmp_path / "cut.bin"
    p.write_bytes(data[:-20])  # into the last GYR message
    i0, _ = read_dataflash(p)
    assert len(i0) == 3
    assert i0.metadata["messages_cut_at_end"] == "0"
    p.write_bytes(data[:-40])  # into the last IMU message: that sample is gone
    i0, _ = read_dataflash(p)
    np.testing.assert_allclose(i0.time_s, [5.0, 5.0025])
    assert i0.metadata["messages_cut_at_end"] == "1"


def test_a_log_whose_only_imu_message_is_cut_is_an_error_naming_the_file(
    tmp_path: Path,
) -> None:
    imu = dataflashkit.IMU
    one = [(imu, [5_000_000, 0, 0.01, 0.0, -0.5, 0.0, 0.0, -9.81, 0, 0, 35.0, 1, 1, 400, 400])]
    data = dataflashkit.log([imu], one)
    p = tmp_path / "cut1.bin"
    p.write_bytes(data[:-5])  # the one IMU message loses its last 5 bytes
    with pytest.raises(RunFileError,
                       match=r"cut1\.bin: every IMU message \(IMU: 1\) is cut short"):
        read_dataflash(p)


@pytest.mark.parametrize(("content", "pattern"), [
    (b"", r"empty\.bin: not a readable ArduPilot DataFlash log"),
    (b"not a dataflash log at all\n" * 20, r"empty\.bin: no IMU message .*formats defined"),
])
def test_not_dataflash(tmp_path: Path, content: bytes, pattern: str) -> None:
    p = tmp_path / "empty.bin"
    p.write_bytes(content)
    with pytest.raises(RunFileError, match=pattern):
        read_dataflash(p)


def test_no_imu_message(tmp_path: Path) -> None:
    p = tmp_path / "gyr.bin"
    p.write_bytes(dataflashkit.no_imu())
    with pytest.raises(RunFileError, match=r"gyr\.bin: no IMU message .*'GYR'"):
        read_dataflash(p)


def test_no_temperature_column(tmp_path: Path) -> None:
    p = tmp_path / "notemp.bin"
    p.write_bytes(dataflashkit.no_temperature())
    with pytest.raises(RunFileError, match=r"notemp\.bin: message 'IMU': missing column\(s\) "
                                           r"\['T \(temperature"):
        read_dataflash(p)
