"""The standard-message views of state and health (client/_ros_diag.py) against an
independent implementation: rosbags' CDR serialiser and its message definitions."""

from __future__ import annotations

import math

import pytest
from rosbags.typesys import Stores, get_typestore

from gyrotherm.client import _ros, _ros_diag
from gyrotherm.codecs._wire import (
    AxisEffects,
    HealthMessage,
    StateMessage,
    StatusFlags,
    ZeroState,
)

STORE = get_typestore(Stores.ROS2_HUMBLE)


@pytest.mark.parametrize(("ours", "name"), [
    (_ros_diag.DIAGNOSTIC_ARRAY_MSGDEF, _ros_diag.DIAGNOSTIC_ARRAY),
    (_ros_diag.VECTOR3_STAMPED_MSGDEF, _ros_diag.VECTOR3_STAMPED),
    (_ros.IMU_MSGDEF, _ros.IMU), (_ros.TEMPERATURE_MSGDEF, _ros.TEMPERATURE)])
def test_message_definitions_are_rosbags_own(ours: str, name: str) -> None:
    assert ours == STORE.generate_msgdef(name, ros_version=2)[0]


def test_diagnostic_array_cdr_is_byte_for_byte_rosbags() -> None:
    cls = STORE.types
    statuses = [(2, "gyrotherm/imu0/state", "BIAS_INVALID", "imu0",
                 [("temperature_c", "21.5"), ("é", "")]), (0, "b", "", "", [])]
    ours = _ros_diag.diagnostic_array_cdr(12.25, "gyro_link", statuses)
    Time, Header = cls["builtin_interfaces/msg/Time"], cls["std_msgs/msg/Header"]
    KV, St = cls["diagnostic_msgs/msg/KeyValue"], cls["diagnostic_msgs/msg/DiagnosticStatus"]
    msg = cls[_ros_diag.DIAGNOSTIC_ARRAY](
        header=Header(stamp=Time(sec=12, nanosec=250_000_000), frame_id="gyro_link"),
        status=[St(level=lvl, name=n, message=m, hardware_id=h,
                   values=[KV(key=k, value=v) for k, v in kv])
                for lvl, n, m, h, kv in statuses])
    assert ours == bytes(STORE.serialize_cdr(msg, _ros_diag.DIAGNOSTIC_ARRAY))


def test_vector3_stamped_cdr_is_byte_for_byte_rosbags() -> None:
    ours = _ros_diag.vector3_stamped_cdr(-0.5, "g", (1.0, -2.5, math.pi))
    back = STORE.deserialize_cdr(ours, _ros_diag.VECTOR3_STAMPED)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (-1, 500_000_000)
    assert (back.vector.x, back.vector.y, back.vector.z) == (1.0, -2.5, math.pi)
    assert ours == bytes(STORE.serialize_cdr(back, _ros_diag.VECTOR3_STAMPED))


def test_state_and_health_statuses() -> None:
    state = StateMessage(
        7, 100.5, 1.7e9, 21.5, 0.02, math.nan, 0.1, (0.1, -0.2, 0.3),
        StatusFlags.ZERO_PENDING | StatusFlags.T_CLAMPED,
        {"x": AxisEffects(21.0, 0.5, 1, 30.0, 0.01)}, ZeroState(1, (0.0, 0.0, 0.0)))
    lvl, name, message, hw, kv = _ros_diag.state_status(state, "imu0")
    values = dict(kv)
    assert (lvl, name, hw) == (_ros_diag.WARN, "gyrotherm/imu0/state", "imu0")
    assert message == "T_CLAMPED ZERO_PENDING"
    assert values["delta_t_c"] == "nan" and float(values["temperature_c"]) == 21.5
    assert values["flags"] == "0x1002" and values["zero.status"] == "pending"
    assert float(values["effects.x.hysteresis_h"]) == 0.5
    assert values["effects.x.hysteresis_direction"] == "1"
    assert _ros_diag.bias_rad_s(state) == pytest.approx(
        tuple(b * math.pi / 180 for b in (0.1, -0.2, 0.3)))
    health = HealthMessage(3, None, 1.7e9, 12.0, 100, 98, {"crc_mismatch": 2},
                           StatusFlags.BIAS_INVALID | StatusFlags(1 << 20), "abc", 1)
    lvl, name, message, _, kv = _ros_diag.health_status(health, "imu0")
    assert lvl == _ros_diag.ERROR and message == "BIAS_INVALID 0x100000"
    assert dict(kv)["drops.crc_mismatch"] == "2" and dict(kv)["sensor_time_s"] == "nan"
    assert _ros_diag.level(0) == _ros_diag.OK
