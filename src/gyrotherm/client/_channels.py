"""The channels gyrotherm offers to ROS 2 / Foxglove consumers, and the sinks they go to.

For a sensor ``S`` (topics after ROS naming, one per stream), every channel ROS 2 CDR
with its message definition, so that ``ros2 bag play`` takes the file (rosbag2 refuses
a bag whose topics mix serialization formats) and no package beyond the standard
messages is needed:

===============================  =================================  =====================
topic                            schema (cdr)                       from
===============================  =================================  =====================
``/gyrotherm/S/imu``             sensor_msgs/msg/Imu                rate: corrected, rad/s
``/gyrotherm/S/imu_raw``         sensor_msgs/msg/Imu                rate: raw, rad/s
``/gyrotherm/S/temperature``     sensor_msgs/msg/Temperature        state: T (°C), σ²
``/gyrotherm/S/delta_t``         sensor_msgs/msg/Temperature        state: ΔT (°C), σ²
``/gyrotherm/S/bias``            geometry_msgs/msg/Vector3Stamped   state: bias, rad/s
``/gyrotherm/S/state``           diagnostic_msgs/msg/DiagnosticArray  state: flags, zero,
                                                                    effects, all fields
``/gyrotherm/S/health``          diagnostic_msgs/msg/DiagnosticArray  health
===============================  =================================  =====================

(:mod:`gyrotherm.client._ros`, :mod:`gyrotherm.client._ros_diag`.) On request
(``json_channels``) two more, ``/gyrotherm/S/state_json`` and ``…/health_json``
(jsonschema/json, the state and health as JSON objects): a file with them mixes
encodings and is **not** playable by ``ros2 bag play``.

**Covariances.** ``imu``: the calibration's residual variance per axis (all zeros,
"unknown" in sensor_msgs/Imu's terms, without one). ``imu_raw``: the raw rate's error
is the bias as well as the noise, so its variance is the residual variance plus the
square of the bias the daemon removes on that sample (°/s² → (rad/s)²); all zeros
(unknown) when the residual variance is unknown. (Element 0 = −1 would tell a
consumer the angular velocity is *absent*, which it is not.)

**Stamps** (``stamp``): ``"receive"`` (default) puts the daemon's receive clock
(``receive_time_s``, the vehicle computer's system clock, what ROS time is) into every
header, so that tools which compare stamps with *now* (rviz's TF lookups,
robot_localization, message filters) take the messages; ``"sensor"`` puts the sensor's
own clock (``sensor_time_s``, often seconds since power-on: dates in 1970 to ROS), the
precise spacing of samples, for offline analysis. The log time of every message is the
daemon's ``receive_time_s`` either way.

:class:`Fanout` turns each decoded message into these channels' payloads and hands
them to every :class:`Sink` (an MCAP file, a Foxglove WebSocket server, a ROS 2 node),
one lock for all (the subscriber's callbacks come from one zenoh thread, but a sink
may be read from another).
"""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

from gyrotherm.client import _ros, _ros_diag
from gyrotherm.codecs._wire import HealthMessage, RateMessage, StateMessage

Stamp = Literal["receive", "sensor"]
STAMPS: tuple[Stamp, ...] = ("receive", "sensor")


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """One channel: topic, schema (name, encoding, text) and message encoding."""

    topic: str
    schema_name: str
    schema_encoding: str  # "ros2msg" or "jsonschema"
    schema_text: str
    message_encoding: str  # "cdr" or "json"


def channel_specs(sensor: str, *, json_channels: bool = False) -> dict[str, ChannelSpec]:
    """The channels of ``sensor``, by short name (imu, imu_raw, temperature, …)."""
    base = f"/gyrotherm/{sensor}"

    def ros(name: str, schema: str, text: str) -> ChannelSpec:
        return ChannelSpec(f"{base}/{name}", schema, "ros2msg", text, "cdr")

    out = {
        "imu": ros("imu", _ros.IMU, _ros.IMU_MSGDEF),
        "imu_raw": ros("imu_raw", _ros.IMU, _ros.IMU_MSGDEF),
        "temperature": ros("temperature", _ros.TEMPERATURE, _ros.TEMPERATURE_MSGDEF),
        "delta_t": ros("delta_t", _ros.TEMPERATURE, _ros.TEMPERATURE_MSGDEF),
        "bias": ros("bias", _ros_diag.VECTOR3_STAMPED, _ros_diag.VECTOR3_STAMPED_MSGDEF),
        "state": ros("state", _ros_diag.DIAGNOSTIC_ARRAY, _ros_diag.DIAGNOSTIC_ARRAY_MSGDEF),
        "health": ros("health", _ros_diag.DIAGNOSTIC_ARRAY, _ros_diag.DIAGNOSTIC_ARRAY_MSGDEF),
    }
    if json_channels:
        out["state_json"] = ChannelSpec(f"{base}/state_json", "gyrotherm.State", "jsonschema",
                                        json.dumps(_ros.STATE_SCHEMA), "json")
        out["health_json"] = ChannelSpec(f"{base}/health_json", "gyrotherm.Health",
                                         "jsonschema", json.dumps(_ros.HEALTH_SCHEMA), "json")
    return out


class Sink(Protocol):
    """Where channel payloads go (an MCAP writer, a WebSocket server)."""

    def add_channel(self, spec: ChannelSpec) -> Any: ...

    def write(self, channel: Any, log_time_ns: int, data: bytes) -> None: ...

    def close(self) -> None: ...


def _ns(t_s: float) -> int:
    return max(0, round(t_s * 1e9))


class Fanout:
    """Subscriber callbacks → ROS/JSON payloads → every sink.

    ``frame_id`` goes into every ROS header (default: the sensor name);
    ``covariance_dps2`` is the per-axis angular-velocity variance in (°/s)² (written
    in (rad/s)²; zeros mean "unknown"); ``stamp``: which clock the headers carry
    (module docstring); ``json_channels``: add the JSON state and health channels."""

    def __init__(
        self, sinks: Sequence[Sink], *, sensor: str, frame_id: str | None = None,
        covariance_dps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
        stamp: Stamp = "receive", json_channels: bool = False,
    ) -> None:  # fmt: skip
        if stamp not in STAMPS:
            raise ValueError(f"stamp {stamp!r}: expected one of {STAMPS}")
        self._lock = threading.Lock()
        self._sinks = list(sinks)
        self.sensor = sensor
        self.frame_id = sensor if frame_id is None else frame_id
        self.covariance_dps2 = covariance_dps2
        self.stamp = stamp
        self.specs = channel_specs(sensor, json_channels=json_channels)
        self._handles = [{k: s.add_channel(spec) for k, spec in self.specs.items()}
                         for s in self._sinks]  # fmt: skip
        self.counts: Counter[str] = Counter()
        self.first_message = threading.Event()
        self.last_message_s = time.monotonic()
        """When the latest message (any stream) arrived, monotonic s (else construction)."""

    def _arrived(self) -> None:
        self.last_message_s = time.monotonic()
        self.first_message.set()

    def _emit(self, name: str, t_ns: int, data: bytes) -> None:
        """Write to every sink; counted by topic (``counts``; also
        ``"unrepresentable_stamp"``: messages whose stamp no ROS 2 Time holds)."""
        for sink, handles in zip(self._sinks, self._handles, strict=True):
            sink.write(handles[name], t_ns, data)
        self.counts[self.specs[name].topic] += 1

    def _header_s(self, sensor_time_s: float | None, receive_time_s: float) -> float:
        return (receive_time_s if self.stamp == "receive" or sensor_time_s is None
                else sensor_time_s)

    def raw_covariance_dps2(self, bias_dps: Sequence[float]) -> tuple[float, float, float]:
        """imu_raw's per-axis variance, (°/s)²: residual variance + bias² (module
        docstring); zeros where the residual variance is unknown."""
        x, y, z = (v + b * b if v > 0.0 else 0.0
                   for v, b in zip(self.covariance_dps2, bias_dps, strict=True))
        return x, y, z

    def on_rate(self, msg: RateMessage) -> None:
        t_ns, cov = _ns(msg.receive_time_s), self.covariance_dps2
        t_s = self._header_s(msg.sensor_time_s, msg.receive_time_s)
        try:
            imu = _ros.imu_cdr(t_s, self.frame_id, msg.rate_dps, cov)
            raw = _ros.imu_cdr(t_s, self.frame_id, msg.raw_rate_dps,
                               self.raw_covariance_dps2(msg.bias_dps))
        except ValueError:  # a stamp no ROS 2 Time can hold: counted, not written
            self.counts["unrepresentable_stamp"] += 1
            self._arrived()
            return
        with self._lock:
            self._emit("imu", t_ns, imu)
            self._emit("imu_raw", t_ns, raw)
        self._arrived()

    def on_state(self, msg: StateMessage) -> None:
        t_ns = _ns(msg.receive_time_s)
        t_s = self._header_s(msg.sensor_time_s, msg.receive_time_s)
        out: list[tuple[str, bytes]] = []
        try:
            out = [
                ("temperature", _ros.temperature_cdr(t_s, self.frame_id, msg.temperature_c,
                                                     msg.temperature_std_c**2)),
                ("delta_t", _ros.temperature_cdr(t_s, self.frame_id, msg.delta_t_c,
                                                 msg.delta_t_std_c**2)),
                ("bias", _ros_diag.vector3_stamped_cdr(t_s, self.frame_id,
                                                       _ros_diag.bias_rad_s(msg))),
                ("state", _ros_diag.diagnostic_array_cdr(
                    t_s, self.frame_id, [_ros_diag.state_status(msg, self.sensor)])),
            ]  # fmt: skip
        except ValueError:  # the JSON state has no such limit: still written
            self.counts["unrepresentable_stamp"] += 1
        if "state_json" in self.specs:
            out.append(("state_json", json.dumps(_ros.state_json(msg)).encode()))
        with self._lock:
            for name, data in out:
                self._emit(name, t_ns, data)
        self._arrived()

    def on_health(self, msg: HealthMessage) -> None:
        t_ns = _ns(msg.receive_time_s)
        t_s = self._header_s(msg.sensor_time_s, msg.receive_time_s)
        out: list[tuple[str, bytes]] = []
        try:
            out.append(("health", _ros_diag.diagnostic_array_cdr(
                t_s, self.frame_id, [_ros_diag.health_status(msg, self.sensor)])))
        except ValueError:
            self.counts["unrepresentable_stamp"] += 1
        if "health_json" in self.specs:
            out.append(("health_json", json.dumps(_ros.health_json(msg)).encode()))
        with self._lock:
            for name, data in out:
                self._emit(name, t_ns, data)
        self._arrived()

    def close(self) -> None:
        with self._lock:
            for sink in self._sinks:
                sink.close()
            self._sinks.clear()
            self._handles.clear()


#: rosbag2's ``offered_qos_profiles`` channel metadata (rosbag2_storage ``qos.cpp``,
#: ``serialize_rclcpp_qos_vector``): one profile, RELIABLE, KEEP_LAST 10, VOLATILE,
#: AUTOMATIC liveliness, default durations, as record's ROS 2 publishers offer. Written
#: with the enum values as integers, the layout before bag metadata version 9, because
#: rosbag2's MCAP reader assumes that layout for a file without its ``rosbag2``
#: metadata record (``mcap_storage.cpp``: "if serialized metadata is not present then
#: metadata_.version < 9").
OFFERED_QOS_YAML = (
    "- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n"
    "  deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n"
    "  liveliness: 1\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n"
    "  avoid_ros_namespace_conventions: false"
)


class McapSink:
    """An MCAP file (profile ``ros2``, zstd chunks). Each CDR channel carries the
    metadata rosbag2's MCAP storage writes (``mcap_storage.cpp``, ``write_topic``):
    ``offered_qos_profiles`` (:data:`OFFERED_QOS_YAML`) and ``topic_type_hash``
    (REP-2016 RIHS01)."""

    def __init__(self, path: str) -> None:
        from mcap.writer import Writer  # lazy: only `gyrotherm record` needs mcap

        self._file = open(path, "wb")  # closed in close()
        self._writer = Writer(self._file)
        self._writer.start(profile="ros2", library="gyrotherm record")
        self._schemas: dict[tuple[str, str], int] = {}
        self._seq: Counter[int] = Counter()

    def add_channel(self, spec: ChannelSpec) -> int:
        from gyrotherm.client._rmw_zenoh import type_hash

        key = (spec.schema_name, spec.schema_text)
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(
                spec.schema_name, spec.schema_encoding, spec.schema_text.encode())
        metadata = ({"offered_qos_profiles": OFFERED_QOS_YAML,
                     "topic_type_hash": type_hash(spec.schema_name)}
                    if spec.message_encoding == "cdr" else {})
        return self._writer.register_channel(topic=spec.topic,
                                             message_encoding=spec.message_encoding,
                                             schema_id=self._schemas[key],
                                             metadata=metadata)  # fmt: skip

    def write(self, channel: int, log_time_ns: int, data: bytes) -> None:
        seq = self._seq[channel]
        self._seq[channel] = (seq + 1) & 0xFFFFFFFF  # MCAP's sequence is a uint32
        self._writer.add_message(channel_id=channel, log_time=log_time_ns, data=data,
                                 publish_time=log_time_ns, sequence=seq)

    def close(self) -> None:
        self._writer.finish()
        self._file.close()
