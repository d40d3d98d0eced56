"""Wire payloads: the msgpack messages the daemon publishes on Zenoh (schema version 1).

Every payload is one msgpack **array** with a fixed field order (no map keys on
the hot path); element 0 is the message kind, element 1 the schema version::

    rate    [1, 1, seq, sensor_time_s, receive_time_s,
             rate_x, rate_y, rate_z, raw_x, raw_y, raw_z, bias_x, bias_y, bias_z, flags]
    state   [2, 1, seq, sensor_time_s, receive_time_s, temperature_c, temperature_std_c,
             delta_t_c, delta_t_std_c, bias_x, bias_y, bias_z, flags]
    health  [3, 1, seq, sensor_time_s | nil, receive_time_s, uptime_s, frames_received,
             frames_published, {reason: count}, flags, calibration_id]
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

Version rule: a decoder accepts only the schema version it knows (1). Fields may be
*appended* within a version (decoders ignore trailing elements) and new flag bits
may be added (decoders keep unknown bits); anything else (removing, reordering,
retyping or changing the unit of a field) needs a new version.

``encode_*`` trust their typed input (hot path: ~1 µs per rate message, see
docs/wire-format.md); ``decode_*`` check everything and raise
:class:`gyrotherm.DecodeError` naming the message, field, index and value.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, TypeVar

import msgpack

from gyrotherm._errors import DecodeError, PublishError

SCHEMA_VERSION = 1
U64_MAX = 2**64 - 1

Vec3 = tuple[float, float, float]
_T = TypeVar("_T")
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


@dataclass(frozen=True, slots=True)
class HealthMessage:
    """Daemon health (key ``…/health``), once a second.

    ``sensor_time_s`` is None before the first frame. ``drops`` counts discarded
    frames by reason (e.g. ``"decode_error"``, ``"counter_jump"``, ``"publish_error"``,
    ``"no_subscriber"``); it is stored as a read-only mapping. ``calibration_id`` is ""
    without calibration.
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
    """Encode a state message (13-element array)."""
    b = msg.bias_dps
    return _pack(
        [2, SCHEMA_VERSION, msg.seq, msg.sensor_time_s, msg.receive_time_s,
         msg.temperature_c, msg.temperature_std_c, msg.delta_t_c, msg.delta_t_std_c,
         b[0], b[1], b[2], int(msg.flags)],
        "state",
    )  # fmt: skip


def _health_list(msg: HealthMessage) -> list[Any]:
    return [
        3, SCHEMA_VERSION, msg.seq, msg.sensor_time_s, msg.receive_time_s, msg.uptime_s,
        msg.frames_received, msg.frames_published, dict(msg.drops), int(msg.flags),
        msg.calibration_id,
    ]  # fmt: skip


def encode_health(msg: HealthMessage) -> bytes:
    """Encode a health message (11-element array)."""
    return _pack(_health_list(msg), "health")


def encode_calibration_info(info: CalibrationInfo) -> bytes:
    """Encode the calibration queryable's reply (5-element array)."""
    cal = None if info.calibration is None else dict(info.calibration)
    health = None if info.health is None else _health_list(info.health)
    return _pack([4, SCHEMA_VERSION, info.calibration_id, cal, health], "calibration")


# ---------------------------------------------------------------- decoding

_Check = Callable[[Any, int, str, str], Any]


def _fail(what: str, index: int, name: str, value: Any, problem: str) -> DecodeError:
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    return DecodeError(f"{what} payload: field '{name}' (index {index}) = {shown} {problem}")


def _u64(v: Any, i: int, name: str, what: str) -> int:
    if type(v) is not int:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected uint64")
    if not 0 <= v <= U64_MAX:
        raise _fail(what, i, name, v, f"is out of range [0, {U64_MAX}]")
    return v


def _float(v: Any, i: int, name: str, what: str) -> float:
    if type(v) is float:
        return v
    if type(v) is int:
        return float(v)
    raise _fail(what, i, name, v, f"is {type(v).__name__}, expected float")


def _finite(v: Any, i: int, name: str, what: str) -> float:
    f = _float(v, i, name, what)
    if not math.isfinite(f):
        raise _fail(what, i, name, v, "is not finite")
    return f


def _opt_finite(v: Any, i: int, name: str, what: str) -> float | None:
    return None if v is None else _finite(v, i, name, what)


_FLOAT_ONLY = {float}
_FLAGS_CACHE = {v: StatusFlags(v) for v in range(256)}  # every combination of bits 0-7


def _to_flags(v: int) -> StatusFlags:
    cached = _FLAGS_CACHE.get(v)
    return StatusFlags(v) if cached is None else cached


def _flags(v: Any, i: int, name: str, what: str) -> StatusFlags:
    return _to_flags(_u64(v, i, name, what))


def _str(v: Any, i: int, name: str, what: str) -> str:
    if type(v) is not str:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected str")
    return v


def _drops(v: Any, i: int, name: str, what: str) -> dict[str, int]:
    if type(v) is not dict:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected map str→uint64")
    for reason, count in v.items():
        _str(reason, i, f"{name} key", what)
        _u64(count, i, f"{name}[{reason!r}]", what)
    return v


def _calibration(v: Any, i: int, name: str, what: str) -> dict[str, Any] | None:
    if v is None:
        return None
    if type(v) is not dict:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected map or nil")
    for key in v:
        _str(key, i, f"{name} key", what)
    return v


def _opt_health(v: Any, i: int, name: str, what: str) -> HealthMessage | None:
    if v is None:
        return None
    if type(v) is not list:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected health array or nil")
    return _decode_fields(v, MessageKind.HEALTH, f"{what}.{name}", _build_health)


def _vec(name: str) -> list[tuple[str, _Check]]:
    return [(f"{name}[{k}]", _float) for k in range(3)]


_SPECS: dict[MessageKind, list[tuple[str, _Check]]] = {
    MessageKind.RATE: [
        ("seq", _u64), ("sensor_time_s", _finite), ("receive_time_s", _finite),
        *_vec("rate_dps"), *_vec("raw_rate_dps"), *_vec("bias_dps"), ("flags", _flags),
    ],
    MessageKind.STATE: [
        ("seq", _u64), ("sensor_time_s", _finite), ("receive_time_s", _finite),
        ("temperature_c", _float), ("temperature_std_c", _float),
        ("delta_t_c", _float), ("delta_t_std_c", _float), *_vec("bias_dps"), ("flags", _flags),
    ],
    MessageKind.HEALTH: [
        ("seq", _u64), ("sensor_time_s", _opt_finite), ("receive_time_s", _finite),
        ("uptime_s", _finite), ("frames_received", _u64), ("frames_published", _u64),
        ("drops", _drops), ("flags", _flags), ("calibration_id", _str),
    ],
    MessageKind.CALIBRATION: [
        ("calibration_id", _str), ("calibration", _calibration), ("health", _opt_health),
    ],
}  # fmt: skip


def _build_rate(v: list[Any]) -> RateMessage:
    return RateMessage(v[0], v[1], v[2], (v[3], v[4], v[5]), (v[6], v[7], v[8]),
                       (v[9], v[10], v[11]), v[12])  # fmt: skip


def _build_state(v: list[Any]) -> StateMessage:
    return StateMessage(v[0], v[1], v[2], v[3], v[4], v[5], v[6], (v[7], v[8], v[9]), v[10])


def _build_health(v: list[Any]) -> HealthMessage:
    return HealthMessage(*v)


def _build_calibration(v: list[Any]) -> CalibrationInfo:
    return CalibrationInfo(*v)


def _decode_fields(
    a: list[Any], kind: MessageKind, what: str, build: Callable[[list[Any]], _T]
) -> _T:
    if len(a) < 2:
        raise DecodeError(f"{what} payload: array has {len(a)} elements, expected kind and version")
    if type(a[0]) is not int or a[0] != kind:
        known = {int(k): k.name.lower() for k in MessageKind}
        got = f"({known[a[0]]}) " if type(a[0]) is int and a[0] in known else ""
        raise _fail(what, 0, "kind", a[0], f"{got}is not {int(kind)} ({kind.name.lower()})")
    if type(a[1]) is not int or a[1] != SCHEMA_VERSION:
        raise _fail(what, 1, "version", a[1], f"is not the supported version {SCHEMA_VERSION}")
    spec = _SPECS[kind]
    if len(a) < 2 + len(spec):
        name = spec[len(a) - 2][0]
        raise DecodeError(
            f"{what} payload: missing field '{name}' (index {len(a)}): "
            f"array has {len(a)} elements, expected {2 + len(spec)}"
        )
    values = [check(a[i], i, name, what) for i, (name, check) in enumerate(spec, start=2)]
    return build(values)


def _unpack(payload: Payload, what: str) -> list[Any]:
    if not isinstance(payload, bytes | bytearray | memoryview):
        raise DecodeError(f"{what} payload: expected bytes, got {type(payload).__name__}")
    try:
        obj = msgpack.unpackb(payload, raw=False, strict_map_key=True)
    except Exception as exc:  # the C unpacker raises several unrelated types on garbage
        raise DecodeError(
            f"{what} payload: not valid msgpack ({len(payload)} bytes): {type(exc).__name__} {exc}"
        ) from exc
    if type(obj) is not list:
        raise DecodeError(f"{what} payload: expected a msgpack array, got {type(obj).__name__}")
    return obj


def decode_rate(payload: Payload) -> RateMessage:
    """Decode a rate payload; DecodeError names the bad field and value."""
    a = _unpack(payload, "rate")
    # Fast path (the hot one): a well-formed version-1 rate array of plain floats.
    if len(a) >= 15 and a[0] == 1 and a[1] == SCHEMA_VERSION:
        seq, t0, t1, flags = a[2], a[3], a[4], a[14]
        if (
            type(seq) is int and 0 <= seq <= U64_MAX
            and type(flags) is int and 0 <= flags <= U64_MAX
            and type(a[0]) is int and type(a[1]) is int
            and set(map(type, a[3:14])) == _FLOAT_ONLY
            and math.isfinite(t0) and math.isfinite(t1)
        ):  # fmt: skip
            return RateMessage(seq, t0, t1, (a[5], a[6], a[7]), (a[8], a[9], a[10]),
                               (a[11], a[12], a[13]), _to_flags(flags))  # fmt: skip
    return _decode_fields(a, MessageKind.RATE, "rate", _build_rate)


def decode_state(payload: Payload) -> StateMessage:
    """Decode a state payload."""
    return _decode_fields(_unpack(payload, "state"), MessageKind.STATE, "state", _build_state)


def decode_health(payload: Payload) -> HealthMessage:
    """Decode a health payload."""
    a = _unpack(payload, "health")
    return _decode_fields(a, MessageKind.HEALTH, "health", _build_health)


def decode_calibration_info(payload: Payload) -> CalibrationInfo:
    """Decode the calibration queryable's reply."""
    a = _unpack(payload, "calibration")
    return _decode_fields(a, MessageKind.CALIBRATION, "calibration", _build_calibration)


_BUILDERS: dict[int, Callable[[list[Any]], Message]] = {
    MessageKind.RATE: _build_rate,
    MessageKind.STATE: _build_state,
    MessageKind.HEALTH: _build_health,
    MessageKind.CALIBRATION: _build_calibration,
}


def decode_message(payload: Payload) -> Message:
    """Decode any payload, dispatching on its kind (element 0)."""
    a = _unpack(payload, "message")
    kind = a[0] if a else None
    if type(kind) is not int or kind not in _BUILDERS:
        raise _fail("message", 0, "kind", kind, f"is not one of {sorted(_BUILDERS)}")
    mk = MessageKind(kind)
    return _decode_fields(a, mk, mk.name.lower(), _BUILDERS[kind])
