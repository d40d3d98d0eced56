"""The channels gyrotherm offers to ROS 2 / Foxglove consumers, and the sinks they go to.

For a sensor ``S`` (topics after ROS naming, one per stream):

========================  ===========================  =========  ======================
topic                     schema                       encoding   from
========================  ===========================  =========  ======================
``/gyrotherm/S/imu``      sensor_msgs/msg/Imu          cdr        rate: corrected, rad/s
``/gyrotherm/S/imu_raw``  sensor_msgs/msg/Imu          cdr        rate: raw, rad/s
``/gyrotherm/S/temperature``  sensor_msgs/msg/Temperature  cdr    state: T (°C), σ²
``/gyrotherm/S/state``    gyrotherm.State (jsonschema)  json      state (°C, °/s, flags)
``/gyrotherm/S/health``   gyrotherm.Health (jsonschema) json      health
========================  ===========================  =========  ======================

:class:`Fanout` turns each decoded message into these channels' payloads and hands
them to every :class:`Sink` (an MCAP file, a Foxglove WebSocket server), one lock
for all (the subscriber's callbacks come from one zenoh thread, but a sink may be
read from another). The log time of every message is the daemon's ``receive_time_s``.
"""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from gyrotherm.client import _ros
from gyrotherm.codecs._wire import HealthMessage, RateMessage, StateMessage


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """One channel: topic, schema (name, encoding, text) and message encoding."""

    topic: str
    schema_name: str
    schema_encoding: str  # "ros2msg" or "jsonschema"
    schema_text: str
    message_encoding: str  # "cdr" or "json"


def channel_specs(sensor: str) -> dict[str, ChannelSpec]:
    """The five channels of ``sensor``, by short name (imu, imu_raw, temperature, …)."""
    base = f"/gyrotherm/{sensor}"
    state_schema = json.dumps(_ros.STATE_SCHEMA)
    health_schema = json.dumps(_ros.HEALTH_SCHEMA)
    return {
        "imu": ChannelSpec(f"{base}/imu", _ros.IMU, "ros2msg", _ros.IMU_MSGDEF, "cdr"),
        "imu_raw": ChannelSpec(f"{base}/imu_raw", _ros.IMU, "ros2msg", _ros.IMU_MSGDEF, "cdr"),
        "temperature": ChannelSpec(f"{base}/temperature", _ros.TEMPERATURE, "ros2msg",
                                   _ros.TEMPERATURE_MSGDEF, "cdr"),
        "state": ChannelSpec(f"{base}/state", "gyrotherm.State", "jsonschema", state_schema,
                             "json"),
        "health": ChannelSpec(f"{base}/health", "gyrotherm.Health", "jsonschema", health_schema,
                              "json"),
    }  # fmt: skip


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
    in (rad/s)²; zeros mean "unknown")."""

    def __init__(
        self, sinks: Sequence[Sink], *, sensor: str, frame_id: str | None = None,
        covariance_dps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:  # fmt: skip
        self._lock = threading.Lock()
        self._sinks = list(sinks)
        self.frame_id = sensor if frame_id is None else frame_id
        self.covariance_dps2 = covariance_dps2
        self.specs = channel_specs(sensor)
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
        ``"unrepresentable_stamp"``: messages whose sensor time no ROS 2 Time holds)."""
        for sink, handles in zip(self._sinks, self._handles, strict=True):
            sink.write(handles[name], t_ns, data)
        self.counts[self.specs[name].topic] += 1

    def on_rate(self, msg: RateMessage) -> None:
        t_ns, cov = _ns(msg.receive_time_s), self.covariance_dps2
        try:
            imu = _ros.imu_cdr(msg.sensor_time_s, self.frame_id, msg.rate_dps, cov)
            raw = _ros.imu_cdr(msg.sensor_time_s, self.frame_id, msg.raw_rate_dps, cov)
        except ValueError:  # a sensor time no ROS 2 Time can hold: counted, not written
            self.counts["unrepresentable_stamp"] += 1
            self._arrived()
            return
        with self._lock:
            self._emit("imu", t_ns, imu)
            self._emit("imu_raw", t_ns, raw)
        self._arrived()

    def on_state(self, msg: StateMessage) -> None:
        t_ns = _ns(msg.receive_time_s)
        temp: bytes | None = None
        try:
            temp = _ros.temperature_cdr(msg.sensor_time_s, self.frame_id, msg.temperature_c,
                                        msg.temperature_std_c**2)  # fmt: skip
        except ValueError:  # the JSON state has no such limit: still written
            self.counts["unrepresentable_stamp"] += 1
        state = json.dumps(_ros.state_json(msg)).encode()
        with self._lock:
            if temp is not None:
                self._emit("temperature", t_ns, temp)
            self._emit("state", t_ns, state)
        self._arrived()

    def on_health(self, msg: HealthMessage) -> None:
        data = json.dumps(_ros.health_json(msg)).encode()
        with self._lock:
            self._emit("health", _ns(msg.receive_time_s), data)
        self._arrived()

    def close(self) -> None:
        with self._lock:
            for sink in self._sinks:
                sink.close()
            self._sinks.clear()
            self._handles.clear()


class McapSink:
    """An MCAP file (profile ``ros2``, zstd chunks): ros2msg/cdr and jsonschema/json channels."""

    def __init__(self, path: str) -> None:
        from mcap.writer import Writer  # lazy: only `gyrotherm record` needs mcap

        self._file = open(path, "wb")  # closed in close()
        self._writer = Writer(self._file)
        self._writer.start(profile="ros2", library="gyrotherm record")
        self._schemas: dict[tuple[str, str], int] = {}
        self._seq: Counter[int] = Counter()

    def add_channel(self, spec: ChannelSpec) -> int:
        key = (spec.schema_name, spec.schema_text)
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(
                spec.schema_name, spec.schema_encoding, spec.schema_text.encode())
        return self._writer.register_channel(topic=spec.topic,
                                             message_encoding=spec.message_encoding,
                                             schema_id=self._schemas[key])  # fmt: skip

    def write(self, channel: int, log_time_ns: int, data: bytes) -> None:
        seq = self._seq[channel]
        self._seq[channel] = (seq + 1) & 0xFFFFFFFF  # MCAP's sequence is a uint32
        self._writer.add_message(channel_id=channel, log_time=log_time_ns, data=data,
                                 publish_time=log_time_ns, sequence=seq)

    def close(self) -> None:
        self._writer.finish()
        self._file.close()
