"""Standard ROS 2 views of the state and health messages, so that a recording holds
nothing but ROS 2 CDR (rosbag2 plays a file only when every topic has one
serialization format: ``SequentialReader::check_topics_serialization_formats``,
ros2/rosbag2 ``rosbag2_cpp/src/rosbag2_cpp/readers/sequential_reader.cpp``).

* ``bias``: geometry_msgs/msg/Vector3Stamped, the bias removed per axis in **rad/s**
  (REP 103), from the state message (``bias_dps`` · π/180);
* ``delta_t``: sensor_msgs/msg/Temperature holding ΔT (°C, a temperature difference)
  and its variance (°C²);
* ``state`` and ``health``: diagnostic_msgs/msg/DiagnosticArray, the ROS convention
  for status (what ``/diagnostics`` carries): one DiagnosticStatus per message, level
  from the flags (:func:`level`), ``name`` ``gyrotherm/<sensor>/state`` or
  ``…/health``, ``message`` the flag names (``ok`` when none), ``hardware_id`` the
  sensor, and every other field as a key-value (values as text: °C, °/s, s; ``nan``
  where the wire has NaN).

Levels: ``ERROR`` (2) when the published rate is not compensated or not to be trusted
(``BIAS_INVALID``, ``NO_CALIBRATION``, ``SENSOR_FAULT``, ``ZERO_FAILED``,
``NON_FINITE``); ``WARN`` (1) for any other flag; ``OK`` (0) with none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from gyrotherm.client._ros import _HEADER_DEFS, _SEP, DEG, _Cdr
from gyrotherm.codecs._wire import HealthMessage, StateMessage, StatusFlags

DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"
#: diagnostic_msgs/msg/DiagnosticArray with its dependencies (ros2msg).
DIAGNOSTIC_ARRAY_MSGDEF = (
    "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n" + _HEADER_DEFS
    + _SEP + "MSG: diagnostic_msgs/DiagnosticStatus\nbyte OK=0\nbyte WARN=1\nbyte ERROR=2\n"
    "byte STALE=3\nbyte level\nstring name\nstring message\nstring hardware_id\n"
    "diagnostic_msgs/KeyValue[] values\n"
    + _SEP + "MSG: diagnostic_msgs/KeyValue\nstring key\nstring value\n"
)
#: geometry_msgs/msg/Vector3Stamped with its dependencies.
VECTOR3_STAMPED_MSGDEF = (
    "std_msgs/Header header\ngeometry_msgs/Vector3 vector\n" + _HEADER_DEFS
    + _SEP + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
)
OK, WARN, ERROR = 0, 1, 2
_ERRORS = (StatusFlags.BIAS_INVALID | StatusFlags.NO_CALIBRATION | StatusFlags.SENSOR_FAULT
           | StatusFlags.ZERO_FAILED | StatusFlags.NON_FINITE)

Status = tuple[int, str, str, str, Sequence[tuple[str, str]]]
"""(level, name, message, hardware_id, key-values) of one DiagnosticStatus."""


def level(flags: int) -> int:
    """The DiagnosticStatus level of a message's flags (module docstring)."""
    if flags & _ERRORS:
        return ERROR
    return WARN if flags else OK


def _flag_names(flags: int) -> str:
    names = [f.name for f in StatusFlags if f and f & flags and f.name]
    unknown = flags & ~sum(int(f) for f in StatusFlags)
    if unknown:
        names.append(f"0x{unknown:x}")
    return " ".join(names) or "ok"


def _text(v: float) -> str:
    return repr(float(v)) if math.isfinite(v) else "nan"


def diagnostic_array_cdr(t_s: float, frame_id: str, statuses: Sequence[Status]) -> bytes:
    """CDR of a diagnostic_msgs/DiagnosticArray."""
    c = _Cdr()
    c.header(t_s, frame_id)
    c.u32(len(statuses))
    for lvl, name, message, hardware_id, values in statuses:
        c.buf += bytes([lvl])  # byte: 1-aligned
        c.string(name)
        c.string(message)
        c.string(hardware_id)
        c.u32(len(values))
        for key, value in values:
            c.string(key)
            c.string(value)
    return bytes(c.buf)


def vector3_stamped_cdr(t_s: float, frame_id: str, xyz: Sequence[float]) -> bytes:
    """CDR of a geometry_msgs/Vector3Stamped."""
    c = _Cdr()
    c.header(t_s, frame_id)
    c.f64(*xyz)
    return bytes(c.buf)


def bias_rad_s(msg: StateMessage) -> tuple[float, float, float]:
    """The state message's bias in rad/s."""
    x, y, z = (b * DEG for b in msg.bias_dps)
    return x, y, z


def state_status(msg: StateMessage, sensor: str) -> Status:
    """The state message as one DiagnosticStatus (module docstring)."""
    flags = int(msg.flags)
    kv: list[tuple[str, str]] = [
        ("seq", str(msg.seq)), ("sensor_time_s", _text(msg.sensor_time_s)),
        ("receive_time_s", _text(msg.receive_time_s)),
        ("temperature_c", _text(msg.temperature_c)),
        ("temperature_std_c", _text(msg.temperature_std_c)),
        ("delta_t_c", _text(msg.delta_t_c)), ("delta_t_std_c", _text(msg.delta_t_std_c)),
        *((f"bias_{a}_dps", _text(b)) for a, b in zip("xyz", msg.bias_dps, strict=True)),
        ("flags", f"0x{flags:x}"),
    ]
    for axis, e in msg.effects.items():
        kv += [(f"effects.{axis}.{k}", _text(v) if isinstance(v, float) else str(v))
               for k, v in e._asdict().items()]
    if msg.zero is not None:
        kv.append(("zero.status", msg.zero.status_name))
        kv += [(f"zero.offset_{a}_dps", _text(z))
               for a, z in zip("xyz", msg.zero.offset_dps, strict=True)]
    return level(flags), f"gyrotherm/{sensor}/state", _flag_names(flags), sensor, kv


def health_status(msg: HealthMessage, sensor: str) -> Status:
    """The health message as one DiagnosticStatus (module docstring)."""
    flags = int(msg.flags)
    kv: list[tuple[str, str]] = [
        ("seq", str(msg.seq)),
        ("sensor_time_s", "nan" if msg.sensor_time_s is None else _text(msg.sensor_time_s)),
        ("receive_time_s", _text(msg.receive_time_s)), ("uptime_s", _text(msg.uptime_s)),
        ("frames_received", str(msg.frames_received)),
        ("frames_published", str(msg.frames_published)),
        *((f"drops.{k}", str(v)) for k, v in sorted(msg.drops.items())),
        ("flags", f"0x{flags:x}"), ("calibration_id", msg.calibration_id),
        ("counter_jumps", str(msg.counter_jumps)),
    ]
    return level(flags), f"gyrotherm/{sensor}/health", _flag_names(flags), sensor, kv
