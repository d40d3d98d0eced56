"""ROS 2 views of gyrotherm's messages: sensor_msgs/Imu, sensor_msgs/Temperature (CDR).

Pure functions, no ROS installation needed: the message definitions (ros2msg text,
as MCAP's ``ros2msg`` schema encoding wants them) and a small hand-written CDR
(little-endian, XCDR1 plain) serialiser for the two messages, plus JSON views of
the state and health messages with their JSON schemas.

Units: gyrotherm publishes °/s; ROS (REP 103) wants rad/s, so ``angular_velocity``
is ``rate_dps · π/180`` and its covariance (°/s)² · (π/180)². ``header.stamp`` is the
sensor time (``sensor_time_s``: the CAN frame's stamp, docs/wire-format.md), split
into sec/nanosec. Orientation and linear acceleration are absent: their covariance's
element 0 is −1 as sensor_msgs/Imu prescribes. An angular-velocity covariance of all
zeros means "unknown" (sensor_msgs/Imu's convention).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from typing import Any

from gyrotherm.codecs._wire import HealthMessage, StateMessage, StatusFlags

DEG = math.pi / 180.0
_SEP = "=" * 80 + "\n"
_HEADER_DEFS = (
    _SEP + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    + _SEP + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)
#: sensor_msgs/msg/Imu with its dependencies (ros2msg, as rosbag2/MCAP store it).
IMU_MSGDEF = (
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
    "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
    "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
    "float64[9] linear_acceleration_covariance\n"
    + _HEADER_DEFS
    + _SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
    + _SEP + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
)
#: sensor_msgs/msg/Temperature with its dependencies.
TEMPERATURE_MSGDEF = (
    "std_msgs/Header header\nfloat64 temperature\nfloat64 variance\n" + _HEADER_DEFS
)

IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
_ABSENT9 = (-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def stamp(t_s: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in s (nanosec in [0, 10⁹)); ValueError when ``sec`` does
    not fit builtin_interfaces/Time's int32 (beyond 2038 or before 1901 as epoch time)."""
    ns = round(t_s * 1e9)
    sec = ns // 1_000_000_000
    if not -(2**31) <= sec < 2**31:
        raise ValueError(f"time stamp {t_s!r} s does not fit a ROS 2 Time (int32 seconds)")
    return sec, ns % 1_000_000_000


class _Cdr:
    """Little-endian plain CDR; alignment counted from after the 4-byte encapsulation."""

    def __init__(self) -> None:
        self.buf = bytearray(b"\x00\x01\x00\x00")  # CDR_LE, options 0

    def _align(self, n: int) -> None:
        self.buf += b"\x00" * (-(len(self.buf) - 4) % n)

    def i32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<i", v)

    def u32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", v)

    def f64(self, *v: float) -> None:
        self._align(8)
        self.buf += struct.pack(f"<{len(v)}d", *v)

    def string(self, s: str) -> None:
        b = s.encode("utf-8") + b"\x00"
        self.u32(len(b))
        self.buf += b

    def header(self, t_s: float, frame_id: str) -> None:
        sec, nsec = stamp(t_s)
        self.i32(sec)
        self.u32(nsec)
        self.string(frame_id)


def imu_cdr(t_s: float, frame_id: str, rate_dps: Sequence[float],
            covariance_dps2: Sequence[float] = (0.0, 0.0, 0.0)) -> bytes:  # fmt: skip
    """CDR of a sensor_msgs/Imu: angular velocity in rad/s, diagonal covariance (rad/s)²
    from per-axis variances in (°/s)²; orientation and acceleration marked absent."""
    c = _Cdr()
    c.header(t_s, frame_id)
    c.f64(0.0, 0.0, 0.0, 1.0)  # orientation (identity, unused: covariance[0] = -1)
    c.f64(*_ABSENT9)
    c.f64(*(r * DEG for r in rate_dps))
    vx, vy, vz = (v * DEG * DEG for v in covariance_dps2)
    c.f64(vx, 0.0, 0.0, 0.0, vy, 0.0, 0.0, 0.0, vz)
    c.f64(0.0, 0.0, 0.0)
    c.f64(*_ABSENT9)
    return bytes(c.buf)


def temperature_cdr(t_s: float, frame_id: str, temperature_c: float, variance_c2: float) -> bytes:
    """CDR of a sensor_msgs/Temperature (°C, variance °C²)."""
    c = _Cdr()
    c.header(t_s, frame_id)
    c.f64(temperature_c, variance_c2)
    return bytes(c.buf)


def residual_variance_dps2(calibration: Mapping[str, Any] | None) -> tuple[float, float, float]:
    """Per-axis (x, y, z) variance of the compensated residual, (°/s)², from a calibration
    file's ``provenance.residuals`` (``"axis:run" → {rms_dps, n}``), pooled over runs
    (Σ n·rms² / Σ n); 0 ("unknown") for an axis without residuals or no calibration."""
    res = (calibration or {}).get("provenance", {}).get("residuals", {})
    out = []
    for axis in ("x", "y", "z"):
        num = den = 0.0
        if isinstance(res, Mapping):
            for key, m in res.items():
                if str(key).split(":", 1)[0] != axis or not isinstance(m, Mapping):
                    continue
                rms, n = m.get("rms_dps"), m.get("n")
                if isinstance(rms, int | float) and isinstance(n, int) and math.isfinite(rms):
                    num += n * float(rms) ** 2
                    den += n
        out.append(num / den if den > 0 else 0.0)
    return out[0], out[1], out[2]


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None  # JSON has no NaN: null = not available


def _flag_names(flags: StatusFlags) -> list[str]:
    return [f.name for f in StatusFlags if f and f in flags and f.name]


def state_json(msg: StateMessage) -> dict[str, Any]:
    """The state message as JSON (°C, °/s; null where the wire has NaN)."""
    return {
        "seq": msg.seq, "sensor_time_s": msg.sensor_time_s,
        "receive_time_s": msg.receive_time_s,
        "temperature_c": _num(msg.temperature_c), "temperature_std_c": _num(msg.temperature_std_c),
        "delta_t_c": _num(msg.delta_t_c), "delta_t_std_c": _num(msg.delta_t_std_c),
        "bias_dps": {a: _num(b) for a, b in zip("xyz", msg.bias_dps, strict=True)},
        "flags": int(msg.flags), "flag_names": _flag_names(msg.flags),
        "effects": {a: {k: (_num(v) if isinstance(v, float) else v)
                        for k, v in e._asdict().items()} for a, e in msg.effects.items()},
        "zero": None if msg.zero is None else {
            "status": msg.zero.status_name,
            "offset_dps": {a: _num(z) for a, z in zip("xyz", msg.zero.offset_dps, strict=True)}},
    }  # fmt: skip



def health_json(msg: HealthMessage) -> dict[str, Any]:
    """The health message as JSON."""
    return {
        "seq": msg.seq, "sensor_time_s": msg.sensor_time_s, "receive_time_s": msg.receive_time_s,
        "uptime_s": msg.uptime_s, "frames_received": msg.frames_received,
        "frames_published": msg.frames_published, "drops": dict(msg.drops),
        "flags": int(msg.flags), "flag_names": _flag_names(msg.flags),
        "calibration_id": msg.calibration_id, "counter_jumps": msg.counter_jumps,
    }  # fmt: skip


_NUM = {"type": ["number", "null"]}
_XYZ = {"type": "object", "properties": {a: _NUM for a in "xyz"}}
_FLAGS = {"flags": {"type": "integer"},
          "flag_names": {"type": "array", "items": {"type": "string"}}}
STATE_SCHEMA: dict[str, Any] = {
    "title": "gyrotherm.State", "type": "object",
    "description": "T, ΔT (°C), their 1σ, bias (°/s) at the temperature rate; docs/wire-format.md",
    "properties": {
        "seq": {"type": "integer"}, "sensor_time_s": {"type": "number"},
        "receive_time_s": {"type": "number"}, "temperature_c": _NUM, "temperature_std_c": _NUM,
        "delta_t_c": _NUM, "delta_t_std_c": _NUM, "bias_dps": _XYZ, **_FLAGS,
        "effects": {"type": "object"},
        "zero": {"type": ["object", "null"], "description": "boot-time zero: status (off, "
                 "pending, done, failed) and offset_dps (x y z, °/s, part of bias_dps)",
                 "properties": {"status": {"type": "string"}, "offset_dps": _XYZ}},
    },
}  # fmt: skip
HEALTH_SCHEMA: dict[str, Any] = {
    "title": "gyrotherm.Health", "type": "object",
    "description": "Daemon health, once a second; docs/wire-format.md",
    "properties": {
        "seq": {"type": "integer"}, "sensor_time_s": _NUM, "receive_time_s": {"type": "number"},
        "uptime_s": {"type": "number"}, "frames_received": {"type": "integer"},
        "frames_published": {"type": "integer"},
        "drops": {"type": "object", "additionalProperties": {"type": "integer"}}, **_FLAGS,
        "calibration_id": {"type": "string"}, "counter_jumps": {"type": "integer"},
    },
}  # fmt: skip
