"""Wire payloads: the msgpack messages the daemon publishes on Zenoh (schema version 1).

Every payload is one msgpack **array** with a fixed field order (no map keys on
the hot path); element 0 is the message kind, element 1 the schema version::

    rate    [1, 1, seq, sensor_time_s, receive_time_s,
             rate_x, rate_y, rate_z, raw_x, raw_y, raw_z, bias_x, bias_y, bias_z, flags]
    state   [2, 1, seq, sensor_time_s, receive_time_s, temperature_c, temperature_std_c,
             delta_t_c, delta_t_std_c, bias_x, bias_y, bias_z, flags, {effects}, [zero],
             [learn]]
    health  [3, 1, seq, sensor_time_s | nil, receive_time_s, uptime_s, frames_received,
             frames_published, {reason: count}, flags, calibration_id, counter_jumps]
    calibration reply
            [4, 1, calibration_id, {calibration} | nil, health array | nil]

* ``seq``: uint64, per key expression, 0 for the publisher's first message and +1
  for each message after it (a restart of the publisher starts again at 0).
* ``sensor_time_s``: the CAN frame's time stamp as python-can delivers it, s
  (float64): the sender's stamp over socketcand (the simulator stamps sensor
  time), the host kernel's receive time on socketcan.
* ``receive_time_s``: wall clock (``time.time()``, s since the Unix epoch, float64)
  when the daemon received the CAN frame; subscribers compute latency against it.
* rates and biases in °/s, temperatures in °C, all float64; ``rate = raw − bias``.
  NaN means "not available" (e.g. ``temperature_c`` before the first temperature frame).
* ``flags``: :class:`StatusFlags` bits as an unsigned integer.
* ``effects`` (state, appended within schema 1, present only while a calibration's
  compensator runs): ``{axis: [structure_temperature_c, hysteresis_h,
  hysteresis_direction, t_on_s, effects_bias_dps]}`` (:class:`AxisEffects`).
* ``zero`` (state, appended within schema 1, present only when the daemon runs a
  boot-time zero; ``effects`` is then always written, ``{}`` when empty):
  ``[status, zero_x_dps, zero_y_dps, zero_z_dps]`` (:class:`ZeroState`; status
  0 off, 1 pending, 2 done, 3 failed; the offsets are part of ``bias_dps``).
* ``learn`` (state, appended within schema 1, present only when the daemon runs
  ``[learn]``; ``effects`` and ``zero`` are then always written, ``zero`` as
  ``[0, 0.0, 0.0, 0.0]`` (off) without a boot-time zero): ``[collecting,
  adopted_time_s, status, warmups_used, {reason: count}, t_min_c, t_max_c,
  candidate_rms_dps, current_rms_dps, need_warmups]`` (:class:`LearnProgress`).

Version rule: a decoder accepts only the schema version it knows (1). Fields may be
*appended* within a version (decoders ignore trailing elements) and new flag bits
may be added (decoders keep unknown bits); anything else (removing, reordering,
retyping or changing the unit of a field) needs a new version.

``encode_*`` trust their typed input (hot path: ~1 µs per rate message, see
docs/wire-format.md); ``decode_*`` (in :mod:`gyrotherm.codecs._wire_decode`) check
everything and raise :class:`gyrotherm.DecodeError` naming the message, field, index
and value.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, NamedTuple

import msgpack

from gyrotherm._errors import PublishError

SCHEMA_VERSION = 1
U64_MAX = 2**64 - 1

Vec3 = tuple[float, float, float]
Payload = bytes | bytearray | memoryview


class MessageKind(enum.IntEnum):
    """Element 0 of every payload: which message the array holds."""

    RATE = 1
    STATE = 2
    HEALTH = 3
    CALIBRATION = 4


class StatusFlags(enum.IntFlag):
    """Status bits carried by every rate, state and health message.

    Unknown bits (added by a newer daemon) are kept, never rejected.
    """

    NONE = 0
    #: bit 0: no temperature frame arrived within the estimator's ``stale_after_s``
    #: (or none yet); T and ΔT are predictions and the bias may drift.
    TEMPERATURE_STALE = 1 << 0
    #: bit 1: estimated T is outside the calibrated range; the bias is evaluated
    #: at the nearest range limit.
    T_CLAMPED = 1 << 1
    #: bit 2: estimated ΔT is outside the calibrated range; clamped likewise.
    DELTA_T_CLAMPED = 1 << 2
    #: bit 3: no calibration loaded: ``bias_dps`` is 0 and the rate is the raw rate.
    NO_CALIBRATION = 1 << 3
    #: bit 4: the estimator gated out the latest temperature reading as a spike.
    ESTIMATOR_REJECTED = 1 << 4
    #: bit 5: the CAN frame counter jumped: frames were lost before the daemon.
    COUNTER_JUMP = 1 << 5
    #: bit 6: the estimator has not converged yet (warm-up after start or re-init).
    ESTIMATOR_WARMUP = 1 << 6
    #: bit 7: reserved for a raw rate at the sensor's full scale; never set by
    #: this version of the daemon.
    RATE_SATURATED = 1 << 7
    #: bit 8: the latest temperature frame's status signal is not 0: the device
    #: reports a fault (its reading is still used; the meaning is device-defined).
    SENSOR_FAULT = 1 << 8
    #: bit 9 (client side): a rate message's corrected, raw or bias value is NaN or
    #: ±inf. Never sent by the daemon: :func:`~gyrotherm.codecs.decode_rate` sets it
    #: on decoding, whatever the publisher, so no consumer sees such a sample as clean.
    NON_FINITE = 1 << 9
    #: bit 10: the calibration evaluated to a non-finite bias (or overflowed) at the
    #: current T, ΔT: ``bias_dps`` is 0 and the rate is the raw rate.
    BIAS_INVALID = 1 << 10
    #: bit 11: the time since power-on fed to the calibration's effects was outside
    #: [0, t_on_max_s] (``warmup``/``drift``, docs/model.md §8): clamped to the limit.
    T_ON_CLAMPED = 1 << 11
    #: bit 12: a boot-time zero is configured and not measured yet (the vehicle has
    #: not been at rest long enough since power-on): the gyro's switch-on offset is
    #: still in the rate (docs/model.md, "Boot-time zero").
    ZERO_PENDING = 1 << 12
    #: bit 13: the boot-time zero found no rest window before its deadline: the
    #: switch-on offset stays in the rate until the next power-on.
    ZERO_FAILED = 1 << 13
    #: bit 14: the boot-time zero in use was measured at a moment the daemon could not
    #: tell the vehicle was at rest (after a restart that could not restore a zero, a
    #: calibration loaded where there was none, a clock step or sensor reboot) and it
    #: does not agree with the previous offset: a steady turn slower than
    #: ``max_offset_dps`` may be in it. Until the next power-on (docs/operations.md,
    #: "Boot-time zero").
    ZERO_UNVERIFIED = 1 << 14


class AxisEffects(NamedTuple):
    """One axis' effects state in a state message (after the latest compensator step)."""

    structure_temperature_c: float
    """T_s, the structure temperature the effects keep (unclamped; NaN: none yet), °C."""
    hysteresis_h: float
    """h ∈ [−1, 1] (0 without a ``hysteresis`` effect)."""
    hysteresis_direction: int
    """d ∈ {−1, 0, +1}, the direction of the last move of T_s."""
    t_on_s: float
    """Time since the gyro's power-on fed to the step (unclamped), s."""
    effects_bias_dps: float
    """The additive effects' part of the bias (without the base polynomial), °/s."""


class ZeroStatus(enum.IntEnum):
    """Where the boot-time zero stands (the state message's ``zero`` element 0;
    :mod:`gyrotherm.compensation._zero`)."""

    OFF = 0
    """Not configured (or no calibration loaded)."""
    PENDING = 1
    """Started, no window accepted yet: the switch-on offset is still in the rate."""
    DONE = 2
    """A window was accepted: z is removed."""
    FAILED = 3
    """No window accepted within ``deadline_s``: z = 0 until the next start."""


class ZeroState(NamedTuple):
    """The boot-time zero in a state message (docs/model.md, "Boot-time zero")."""

    status: int
    """0 off, 1 pending, 2 done, 3 failed (:class:`ZeroStatus`)."""
    offset_dps: Vec3
    """z per axis (x, y, z), °/s: included in ``bias_dps``; zeros unless done."""

    @property
    def status_name(self) -> str:
        """"off", "pending", "done" or "failed" (the number as text if unknown)."""
        try:
            return ZeroStatus(self.status).name.lower()
        except ValueError:
            return str(self.status)


@dataclass(frozen=True, slots=True)
class RateMessage:
    """One corrected rate sample (key ``…/rate``), one per rate frame; rates in °/s."""

    seq: int
    sensor_time_s: float
    receive_time_s: float
    rate_dps: Vec3
    raw_rate_dps: Vec3
    bias_dps: Vec3
    flags: StatusFlags = StatusFlags.NONE


@dataclass(frozen=True, slots=True)
class LearnProgress:
    """Learning in the field (the state message's ``learn``; docs/wire-format.md)."""

    collecting: bool
    """A warm-up is being collected now (since the latest power-on)."""
    adopted_time_s: float
    """When the learnt calibration in use was adopted (Unix time, s); NaN: none."""
    status: str
    """One line: ``learning: need 2 more warm-ups``, ``adopted at …`` …"""
    warmups_used: int
    rejected: Mapping[str, int]
    """Warm-ups left out, by reason (``motion``, ``too_short``, ``clock_jump``,
    ``restart``)."""
    t_min_c: float
    """Lowest temperature covered by the warm-ups used, °C (NaN: none yet)."""
    t_max_c: float
    candidate_rms_dps: float
    """Held-out bias error of the learnt model, the largest over the axes, °/s (NaN:
    not validated yet)."""
    current_rms_dps: float
    """The same for the calibration in use (no compensation without one), °/s."""
    need_warmups: int
    """Warm-ups still needed before the gates can pass (0: enough)."""

    def to_list(self) -> list[Any]:
        return [self.collecting, float(self.adopted_time_s), self.status, self.warmups_used,
                dict(self.rejected), float(self.t_min_c), float(self.t_max_c),
                float(self.candidate_rms_dps), float(self.current_rms_dps),
                self.need_warmups]


@dataclass(frozen=True, slots=True)
class StateMessage:
    """Thermal state (key ``…/state``) at the temperature rate: T, ΔT (°C), bias (°/s)."""

    seq: int
    sensor_time_s: float
    receive_time_s: float
    temperature_c: float
    temperature_std_c: float
    delta_t_c: float
    delta_t_std_c: float
    bias_dps: Vec3
    flags: StatusFlags = StatusFlags.NONE
    effects: Mapping[str, AxisEffects] = field(default_factory=dict)
    """Per axis (appended in schema 1): empty without a running compensator or from a
    publisher that predates it."""
    zero: ZeroState | None = None
    """The boot-time zero (appended in schema 1): None when the daemon runs none, or
    from a publisher that predates it."""
    learn: LearnProgress | None = None
    """Learning progress (appended in schema 1): None without ``[learn]``."""


@dataclass(frozen=True, slots=True)
class HealthMessage:
    """Daemon health (key ``…/health``), once a second.

    ``sensor_time_s`` is None before the first frame. ``drops`` counts discarded
    frames by reason (e.g. ``"decode_error"``, ``"counter_jump"``, ``"publish_error"``,
    ``"no_subscriber"``); it is stored as a read-only mapping. ``calibration_id`` is ""
    without calibration. ``counter_jumps`` counts CAN counter jumps of both mapped
    messages since start, delivered or rejected (appended in schema 1: 0 when the
    publisher predates it).
    """

    seq: int
    sensor_time_s: float | None
    receive_time_s: float
    uptime_s: float
    frames_received: int
    frames_published: int
    drops: Mapping[str, int]
    flags: StatusFlags = StatusFlags.NONE
    calibration_id: str = ""
    counter_jumps: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "drops", MappingProxyType(dict(self.drops)))


@dataclass(frozen=True, slots=True)
class CalibrationInfo:
    """Reply of the ``…/calibration`` queryable: the loaded calibration and current health.

    ``calibration`` is the calibration file's content as a JSON-compatible mapping
    (read-only at top level), None when none is loaded.
    """

    calibration_id: str
    calibration: Mapping[str, Any] | None
    health: HealthMessage | None

    def __post_init__(self) -> None:
        if self.calibration is not None:
            object.__setattr__(self, "calibration", MappingProxyType(dict(self.calibration)))


Message = RateMessage | StateMessage | HealthMessage | CalibrationInfo

_packb = msgpack.packb


def _pack(obj: list[Any], what: str) -> bytes:
    try:
        out: bytes = _packb(obj)
    except (TypeError, ValueError, OverflowError) as exc:
        raise PublishError(f"{what} message: cannot encode to msgpack: {exc}") from exc
    return out


def encode_rate(msg: RateMessage) -> bytes:
    """Encode a rate message (15-element array, ~110 bytes)."""
    r, w, b = msg.rate_dps, msg.raw_rate_dps, msg.bias_dps
    return encode_rate_values(msg.seq, msg.sensor_time_s, msg.receive_time_s,
                              r[0], r[1], r[2], w[0], w[1], w[2], b[0], b[1], b[2],
                              int(msg.flags))  # fmt: skip


def encode_rate_values(
    seq: int, sensor_time_s: float, receive_time_s: float,
    rate_x: float, rate_y: float, rate_z: float,
    raw_x: float, raw_y: float, raw_z: float,
    bias_x: float, bias_y: float, bias_z: float, flags: int,
) -> bytes:  # fmt: skip
    """:func:`encode_rate` from plain values, the same bytes (the daemon's hot path:
    no :class:`RateMessage` is built, ~1 µs less per rate frame)."""
    return _pack(
        [1, SCHEMA_VERSION, seq, sensor_time_s, receive_time_s, rate_x, rate_y, rate_z,
         raw_x, raw_y, raw_z, bias_x, bias_y, bias_z, flags],
        "rate",
    )  # fmt: skip


def encode_state(msg: StateMessage) -> bytes:
    """Encode a state message (13-element array; 14 with ``effects``, only when not
    empty; 15 with ``zero``, ``effects`` then written even when empty; 16 with
    ``learn``, ``zero`` then written as off when there is none)."""
    b = msg.bias_dps
    out: list[Any] = [2, SCHEMA_VERSION, msg.seq, msg.sensor_time_s, msg.receive_time_s,
           msg.temperature_c, msg.temperature_std_c, msg.delta_t_c, msg.delta_t_std_c,
           b[0], b[1], b[2], int(msg.flags)]  # fmt: skip
    learn = msg.learn
    if msg.effects or msg.zero is not None or learn is not None:
        out.append({a: [float(e[0]), float(e[1]), int(e[2]), float(e[3]), float(e[4])]
                    for a, e in msg.effects.items()})
    if msg.zero is not None:
        z = msg.zero.offset_dps
        out.append([int(msg.zero.status), float(z[0]), float(z[1]), float(z[2])])
    elif learn is not None:
        out.append([0, 0.0, 0.0, 0.0])  # off: an older decoder reads a valid zero
    if learn is not None:
        out.append(learn.to_list())
    return _pack(out, "state")


def _health_list(msg: HealthMessage) -> list[Any]:
    return [
        3, SCHEMA_VERSION, msg.seq, msg.sensor_time_s, msg.receive_time_s, msg.uptime_s,
        msg.frames_received, msg.frames_published, dict(msg.drops), int(msg.flags),
        msg.calibration_id, msg.counter_jumps,
    ]  # fmt: skip


def encode_health(msg: HealthMessage) -> bytes:
    """Encode a health message (11-element array)."""
    return _pack(_health_list(msg), "health")


def encode_calibration_info(info: CalibrationInfo) -> bytes:
    """Encode the calibration queryable's reply (5-element array)."""
    cal = None if info.calibration is None else dict(info.calibration)
    health = None if info.health is None else _health_list(info.health)
    return _pack([4, SCHEMA_VERSION, info.calibration_id, cal, health], "calibration")
