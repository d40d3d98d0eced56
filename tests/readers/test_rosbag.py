"""rosbag2/MCAP reader: bags written with rosbags' own writer (tests/rosbagkit.py), bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin

import rosbagkit
from gyrotherm import RunFileError
from gyrotherm.readers._rosbag import read_rosbag

DATA = Path(__file__).parents[1] / "data"
BAG = DATA / "rosbag2_imu"
MCAP = DATA / "imu.mcap"


@pytest.mark.parametrize("path", [BAG, BAG / "rosbag2_imu.db3", MCAP],
                         ids=["bag-dir", "db3-file", "mcap-file"])
def test_imu_with_held_temperature(path: Path) -> None:
    (run,) = read_rosbag(path)
    assert run.name == f"{path.stem}:/imu/data"
    assert run.metadata["format"] == ("mcap" if path.suffix == ".mcap" else "rosbag2")
    assert run.metadata["device_id"] == "/imu/data"
    assert run.metadata["frame_id"] == "imu_link"
    assert run.metadata["temperature_topic"] == "/imu/temperature"
    # header.stamp, s since the epoch: samples at +10..50 ms (the one at +0 ms precedes
    # the first temperature, +5 ms, and is dropped)
    np.testing.assert_allclose(run.time_s - 1_700_000_000, [0.01, 0.02, 0.03, 0.04, 0.05],
                               rtol=0, atol=5e-7)
    assert run.metadata["rows_before_first_temperature"] == "1"
    # temperature held from the latest earlier message: 36.5 °C (+5 ms), 37.0 (+25), 37.5 (+45)
    np.testing.assert_allclose(run.temperature_c, [36.5, 36.5, 37.0, 37.0, 37.5])
    # 0.01·k rad/s → 0.5729578·k °/s; π/4 rad/s = 45 °/s; -0.02 rad/s = -1.1459156 °/s
    np.testing.assert_allclose(run.rates_dps["x"], 0.5729578 * np.arange(1, 6), rtol=1e-6)
    np.testing.assert_allclose(run.rates_dps["y"], -1.1459156, rtol=1e-6)
    np.testing.assert_allclose(run.rates_dps["z"], 45.0, rtol=1e-12)
    np.testing.assert_allclose(run.extra["accel_y_mps2"], 0.1 * np.arange(1, 6), rtol=1e-12)
    np.testing.assert_allclose(run.extra["accel_z_mps2"], 9.81, rtol=1e-12)
    assert len(run.sha256) == 64


def test_bag_written_now_matches_committed(tmp_path: Path) -> None:
    for storage in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
        (run,) = read_rosbag(rosbagkit.one_imu(tmp_path / storage.name, storage=storage))
        (ref,) = read_rosbag(BAG)
        np.testing.assert_array_equal(run.time_s, ref.time_s)
        np.testing.assert_array_equal(run.rates_dps["x"], ref.rates_dps["x"])


def test_temperature_topic_paired_by_namespace(tmp_path: Path) -> None:
    imu0, imu1 = read_rosbag(rosbagkit.two_namespaced_imus(tmp_path / "two"))
    assert imu0.metadata["temperature_topic"] == "/imu0/temperature"
    assert imu1.metadata["temperature_topic"] == "/imu1/temperature"
    np.testing.assert_allclose(imu0.temperature_c, [20.0, 21.0, 22.0])
    np.testing.assert_allclose(imu1.temperature_c, [60.0, 59.0, 58.0])
    np.testing.assert_allclose(imu0.rates_dps["z"], 180.0)
    np.testing.assert_allclose(imu1.rates_dps["x"], -180.0)
    assert "accel_x_mps2" in imu0.extra
    assert imu1.extra == {}  # linear_acceleration_covariance[0] = -1: no accelerometer
    assert [r.metadata["instance"] for r in (imu0, imu1)] == ["0", "1"]


def test_imu_topic_and_temperature_topic_chosen(tmp_path: Path) -> None:
    bag = rosbagkit.two_namespaced_imus(tmp_path / "two")
    (run,) = read_rosbag(bag, imu_topic="/imu1/data", temperature_topic="/imu0/temperature")
    np.testing.assert_allclose(run.temperature_c, [20.0, 21.0, 22.0])
    with pytest.raises(RunFileError, match=r"IMU topic '/nope' is not a sensor_msgs/msg/Imu "
                                           r"topic .*candidates: \['/imu0/data', '/imu1/data'\]"):
        read_rosbag(bag, imu_topic="/nope")
    with pytest.raises(RunFileError, match=r"temperature topic '/imu0/data' is not a "
                                           r"sensor_msgs/msg/Temperature topic"):
        read_rosbag(bag, temperature_topic="/imu0/data")


def test_ambiguous_temperature_topics_listed(tmp_path: Path) -> None:
    topics = {"/a/temperature": rosbagkit.TEMPERATURE, "/b/temperature": rosbagkit.TEMPERATURE,
              "/imu": rosbagkit.IMU}
    ns = rosbagkit.T0_NS
    bag = rosbagkit.write_bag(tmp_path / "amb", topics, [
        ("/a/temperature", ns, rosbagkit.temperature_msg(ns, "a", 20.0)),
        ("/b/temperature", ns, rosbagkit.temperature_msg(ns, "b", 30.0)),
        ("/imu", ns + 1, rosbagkit.imu_msg(ns + 1, "imu", (0.0, 0.0, math.pi), None))])
    with pytest.raises(RunFileError, match=r"amb: IMU topic '/imu': several sensor_msgs/msg/"
                                           r"Temperature topics \['/a/temperature', "
                                           r"'/b/temperature'\]; name one"):
        read_rosbag(bag)


def test_no_temperature_topic(tmp_path: Path) -> None:
    bag = rosbagkit.one_imu(tmp_path / "notemp", with_temperature=False)
    with pytest.raises(RunFileError, match=r"notemp: IMU topic '/imu/data': no sensor_msgs/msg/"
                                           r"Temperature topic"):
        read_rosbag(bag)


def test_no_imu_topic(tmp_path: Path) -> None:
    ns = rosbagkit.T0_NS
    bag = rosbagkit.write_bag(tmp_path / "noimu", {"/t": rosbagkit.TEMPERATURE},
                              [("/t", ns, rosbagkit.temperature_msg(ns, "t", 20.0))])
    with pytest.raises(RunFileError, match=r"noimu: no sensor_msgs/msg/Imu topic in the bag "
                                           r"\(topics: \['/t \[sensor_msgs/msg/Temperature\]'\]"):
        read_rosbag(bag)


def test_angular_velocity_marked_absent(tmp_path: Path) -> None:
    topics = {"/t": rosbagkit.TEMPERATURE, "/imu": rosbagkit.IMU}
    ns = rosbagkit.T0_NS
    bag = rosbagkit.write_bag(tmp_path / "orient", topics, [
        ("/t", ns, rosbagkit.temperature_msg(ns, "t", 20.0)),
        ("/imu", ns + 1, rosbagkit.imu_msg(ns + 1, "imu", None, (0.0, 0.0, 9.8))),
        ("/imu", ns + 2, rosbagkit.imu_msg(ns + 2, "imu", None, (0.0, 0.0, 9.8)))])
    with pytest.raises(RunFileError, match=r"orient: IMU topic '/imu' frame_id 'imu': no "
                                           r"finite samples in 2"):
        read_rosbag(bag)


def test_truncated_mcap(tmp_path: Path) -> None:
    data = MCAP.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(RunFileError, match=r"cut\.mcap: ") as exc:
        read_rosbag(cut)
    assert exc.value.__cause__ is not None


def test_not_a_bag(tmp_path: Path) -> None:
    d = tmp_path / "empty_dir"
    d.mkdir()
    with pytest.raises(RunFileError, match=r"empty_dir: not a readable rosbag2/MCAP file"):
        read_rosbag(d)


def test_real_ros2_bag_without_imu_lists_its_topics() -> None:
    with pytest.raises(RunFileError, match=r"ros2_talker\.mcap: no sensor_msgs/msg/Imu topic in "
                                           r"the bag \(topics: .*'/topic \[std_msgs/msg/String\]'"):
        read_rosbag(DATA / "ros2_talker.mcap")
