"""rosbag2 and MCAP fixtures written with rosbags' own writer (``rosbags.rosbag2.Writer``,
sqlite3 and MCAP storage plugins; messages serialised by rosbags' ROS 2 type store),
not with gyrotherm's reader.

``python tests/rosbagkit.py`` regenerates ``tests/data/rosbag2_imu`` (a sqlite3
bag directory) and ``tests/data/imu.mcap`` (the MCAP file of an MCAP-storage bag).
"""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_HUMBLE)
IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
T0_NS = 1_700_000_000 * 1_000_000_000  # 2023-11-14 22:13:20 UTC

# IMU samples: (ns after T0, wx, wy, wz rad/s, ax, ay, az m/s²)
IMU_SAMPLES = [(k * 10_000_000, 0.01 * k, -0.02, math.pi / 4, 0.0, 0.1 * k, 9.81)
               for k in range(6)]
# Temperatures: (ns after T0, °C): the first IMU sample (0 ns) precedes them
TEMPERATURES = [(5_000_000, 36.5), (25_000_000, 37.0), (45_000_000, 37.5)]


def _header(ns: int, frame: str) -> object:
    h = STORE.types["std_msgs/msg/Header"]
    t = STORE.types["builtin_interfaces/msg/Time"]
    return h(stamp=t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)


def imu_msg(ns: int, frame: str, w: Sequence[float] | None,
            a: Sequence[float] | None) -> bytes:
    v3 = STORE.types["geometry_msgs/msg/Vector3"]
    w_cov = np.zeros(9)
    if w is None:
        w_cov[0] = -1.0
        w = (0.0, 0.0, 0.0)
    q = STORE.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    acc_cov = np.zeros(9)
    if a is None:  # REP 145: covariance[0] = -1 marks the field as absent
        acc_cov[0] = -1.0
        a = (0.0, 0.0, 0.0)
    msg = STORE.types[IMU](
        header=_header(ns, frame), orientation=q, orientation_covariance=np.full(9, -1.0),
        angular_velocity=v3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=w_cov,
        linear_acceleration=v3(x=a[0], y=a[1], z=a[2]), linear_acceleration_covariance=acc_cov)
    return bytes(STORE.serialize_cdr(msg, IMU))


def temperature_msg(ns: int, frame: str, celsius: float) -> bytes:
    msg = STORE.types[TEMPERATURE](header=_header(ns, frame), temperature=celsius, variance=0.0)
    return bytes(STORE.serialize_cdr(msg, TEMPERATURE))


def write_bag(path: Path, topics: dict[str, str],
              messages: Sequence[tuple[str, int, bytes]], *,
              storage: StoragePlugin = StoragePlugin.SQLITE3) -> Path:
    """A bag at ``path`` with ``topics`` (name → type) and ``(topic, log ns, cdr)``."""
    with Writer(path, version=8, storage_plugin=storage) as w:
        conns = {t: w.add_connection(t, m, typestore=STORE) for t, m in topics.items()}
        for topic, ns, data in messages:
            w.write(conns[topic], ns, data)
    return path


def one_imu(path: Path, *, storage: StoragePlugin = StoragePlugin.SQLITE3,
            with_temperature: bool = True, imu_topic: str = "/imu/data") -> Path:
    """``/imu/data`` (frame ``imu_link``) and ``/imu/temperature``, in time order."""
    msgs = [(imu_topic, T0_NS + ns + 1000, imu_msg(T0_NS + ns, "imu_link", (wx, wy, wz),
                                                    (ax, ay, az)))
            for ns, wx, wy, wz, ax, ay, az in IMU_SAMPLES]
    topics = {imu_topic: IMU}
    if with_temperature:
        topics["/imu/temperature"] = TEMPERATURE
        msgs += [("/imu/temperature", T0_NS + ns + 1000, temperature_msg(T0_NS + ns, "imu_link",
                                                                         c))
                 for ns, c in TEMPERATURES]
    msgs.sort(key=lambda m: m[1])
    return write_bag(path, topics, msgs, storage=storage)


def two_namespaced_imus(path: Path) -> Path:
    """``/imu0/data`` + ``/imu0/temperature`` and ``/imu1/data`` + ``/imu1/temperature``;
    imu1 without accelerometer (covariance[0] = -1)."""
    topics = {"/imu0/data": IMU, "/imu0/temperature": TEMPERATURE,
              "/imu1/data": IMU, "/imu1/temperature": TEMPERATURE}
    msgs = []
    for k in range(3):
        ns = T0_NS + k * 10_000_000
        msgs += [("/imu0/temperature", ns, temperature_msg(ns, "imu0", 20.0 + k)),
                 ("/imu1/temperature", ns, temperature_msg(ns, "imu1", 60.0 - k)),
                 ("/imu0/data", ns + 1, imu_msg(ns + 1, "imu0", (0.0, 0.0, math.pi), (0, 0, 9.8))),
                 ("/imu1/data", ns + 1, imu_msg(ns + 1, "imu1", (-math.pi, 0.0, 0.0), None))]
    return write_bag(path, topics, msgs)


def regenerate(data: Path) -> None:
    shutil.rmtree(data / "rosbag2_imu", ignore_errors=True)
    one_imu(data / "rosbag2_imu")
    with tempfile.TemporaryDirectory() as tmp:
        bag = one_imu(Path(tmp) / "bag", storage=StoragePlugin.MCAP)
        (mcap,) = bag.glob("*.mcap")
        shutil.copyfile(mcap, data / "imu.mcap")


if __name__ == "__main__":
    regenerate(Path(__file__).parent / "data")
