"""ROS 1 bags (``#ROSBAG V2.0``) are read like rosbag2: written here with rosbags' own
ROS 1 writer and Noetic type store (not with gyrotherm's reader), read back by content
whatever the file is called, values checked against what was written."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from gyrotherm._errors import RunFileError
from gyrotherm.readers import InputSpec, read_runs

STORE = get_typestore(Stores.ROS1_NOETIC)
IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
T0_NS = 1_600_000_000 * 1_000_000_000
SAMPLES = [(k * 20_000_000, 0.001 * k, -0.02, math.pi / 8) for k in range(8)]


def _header(seq: int, ns: int) -> object:
    time = STORE.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    return STORE.types["std_msgs/msg/Header"](seq=seq, stamp=time, frame_id="imu_link")


def _imu(seq: int, ns: int, w: tuple[float, float, float]) -> bytes:
    v3 = STORE.types["geometry_msgs/msg/Vector3"]
    q = STORE.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    msg = STORE.types[IMU](
        header=_header(seq, ns), orientation=q, orientation_covariance=np.full(9, -1.0),
        angular_velocity=v3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9))
    return bytes(STORE.serialize_ros1(msg, IMU))


def _temperature(seq: int, ns: int, celsius: float) -> bytes:
    msg = STORE.types[TEMPERATURE](header=_header(seq, ns), temperature=celsius, variance=0.0)
    return bytes(STORE.serialize_ros1(msg, TEMPERATURE))


def write_ros1_bag(path: Path) -> Path:
    with Writer(path) as w:
        imu = w.add_connection("/imu/data", IMU, typestore=STORE)
        temp = w.add_connection("/imu/temperature", TEMPERATURE, typestore=STORE)
        w.write(temp, T0_NS, _temperature(0, T0_NS, 31.25))
        for k, (ns, wx, wy, wz) in enumerate(SAMPLES):
            w.write(imu, T0_NS + ns + 1, _imu(k, T0_NS + ns, (wx, wy, wz)))
    return path


@pytest.mark.parametrize("name", ["imu.bag", "imu.dat", "imu"])
def test_ros1_bag_read_by_content(tmp_path: Path, name: str) -> None:
    path = write_ros1_bag(tmp_path / name)
    assert path.read_bytes().startswith(b"#ROSBAG V2.0")
    (run,) = read_runs(path, spec=InputSpec())
    assert run.metadata["format"] == "rosbag1"
    assert run.metadata["device_id"] == "/imu/data"
    want_t = np.array([(T0_NS + ns) // 10**9 + ((T0_NS + ns) % 10**9) * 1e-9
                       for ns, *_ in SAMPLES])
    np.testing.assert_array_equal(run.time_s, want_t)
    np.testing.assert_array_equal(run.temperature_c, np.full(len(SAMPLES), 31.25))
    for axis, k in (("x", 1), ("y", 2), ("z", 3)):
        np.testing.assert_allclose(run.rates_dps[axis],
                                   [math.degrees(s[k]) for s in SAMPLES], rtol=0, atol=1e-12)


def test_ros1_bag_cut_is_refused_in_one_line(tmp_path: Path) -> None:
    data = write_ros1_bag(tmp_path / "imu.bag").read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) * 6 // 10])
    with pytest.raises(RunFileError, match=r"cut.bag: not a readable ROS 1 bag") as info:
        read_runs(cut, spec=InputSpec())
    assert "\n" not in str(info.value)
