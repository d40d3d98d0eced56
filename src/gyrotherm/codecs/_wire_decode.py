"""Decoding of the wire payloads (schema version 1) with every field checked.

The layout and the version rule are in :mod:`gyrotherm.codecs._wire` and
docs/wire-format.md. ``decode_*`` accept ``bytes``, ``bytearray`` or
``memoryview``; they check the message kind, the schema version, the field count
and every field's type and range, and raise :class:`gyrotherm.DecodeError`
naming the message, field, index and value. Trailing elements (fields appended
within the version) are ignored; unknown flag bits are kept.

A rate message whose corrected, raw or bias values are not all finite (NaN,
±inf) is decoded, not refused (NaN is the wire's "not available"), with
:attr:`StatusFlags.NON_FINITE` added to its flags: a consumer testing
``if msg.flags:`` never takes it for a clean sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar

import msgpack

from gyrotherm._errors import DecodeError
from gyrotherm.codecs._wire import (
    SCHEMA_VERSION,
    U64_MAX,
    AxisEffects,
    CalibrationInfo,
    HealthMessage,
    LearnProgress,
    Message,
    MessageKind,
    Payload,
    RateMessage,
    StateMessage,
    StatusFlags,
    ZeroState,
)

_T = TypeVar("_T")

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
_FLAGS_CACHE = {v: StatusFlags(v) for v in range(4096)}  # every combination of bits 0-11
_NON_FINITE = int(StatusFlags.NON_FINITE)
_isfinite = math.isfinite


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


_AXES = ("x", "y", "z")


def _effects(v: Any, i: int, name: str, what: str) -> dict[str, AxisEffects]:
    if type(v) is not dict:
        raise _fail(what, i, name, v, f"is {type(v).__name__}, expected map axis→array")
    out = {}
    for axis, e in v.items():
        if axis not in _AXES:
            raise _fail(what, i, f"{name} key", axis, f"is not an axis {_AXES}")
        where = f"{name}[{axis!r}]"
        if type(e) is not list or len(e) < 5:
            raise _fail(what, i, where, e, "is not an array of 5 elements")
        d = e[2]
        if type(d) is not int or d not in (-1, 0, 1):
            raise _fail(what, i, f"{where}.hysteresis_direction", d, "is not -1, 0 or 1")
        out[axis] = AxisEffects(_float(e[0], i, f"{where}.structure_temperature_c", what),
                                _float(e[1], i, f"{where}.hysteresis_h", what), d,
                                _float(e[3], i, f"{where}.t_on_s", what),
                                _float(e[4], i, f"{where}.effects_bias_dps", what))
    return out


def _learn(v: Any, i: int, name: str, what: str) -> LearnProgress:
    if type(v) is not list or len(v) < 10:
        raise _fail(what, i, name, v, "is not an array of 10 elements")
    if type(v[0]) is not bool:
        raise _fail(what, i, f"{name}.collecting", v[0], "is not a boolean")
    return LearnProgress(v[0], _float(v[1], i, f"{name}.adopted_time_s", what),
                         _str(v[2], i, f"{name}.status", what),
                         _u64(v[3], i, f"{name}.warmups_used", what),
                         _drops(v[4], i, f"{name}.rejected", what),
                         _float(v[5], i, f"{name}.t_min_c", what),
                         _float(v[6], i, f"{name}.t_max_c", what),
                         _float(v[7], i, f"{name}.candidate_rms_dps", what),
                         _float(v[8], i, f"{name}.current_rms_dps", what),
                         _u64(v[9], i, f"{name}.need_warmups", what))


def _zero(v: Any, i: int, name: str, what: str) -> ZeroState:
    if type(v) is not list or len(v) < 4:
        raise _fail(what, i, name, v, "is not an array of 4 elements")
    if type(v[0]) is not int or not 0 <= v[0] <= 3:
        raise _fail(what, i, f"{name}.status", v[0], "is not 0, 1, 2 or 3")
    return ZeroState(v[0], (_float(v[1], i, f"{name}.offset_dps[0]", what),
                            _float(v[2], i, f"{name}.offset_dps[1]", what),
                            _float(v[3], i, f"{name}.offset_dps[2]", what)))


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

#: Fields appended within schema 1: (name, check, value when the array ends before it).
_APPENDED: dict[MessageKind, list[tuple[str, _Check, Any]]] = {
    MessageKind.HEALTH: [("counter_jumps", _u64, 0)],
    MessageKind.STATE: [("effects", _effects, {}), ("zero", _zero, None),
                        ("learn", _learn, None)],
}


def _build_rate(v: list[Any]) -> RateMessage:
    flags = v[12]
    if not all(map(_isfinite, v[3:12])):
        flags = _to_flags(int(flags) | _NON_FINITE)
    return RateMessage(v[0], v[1], v[2], (v[3], v[4], v[5]), (v[6], v[7], v[8]),
                       (v[9], v[10], v[11]), flags)  # fmt: skip


def _build_state(v: list[Any]) -> StateMessage:
    return StateMessage(v[0], v[1], v[2], v[3], v[4], v[5], v[6], (v[7], v[8], v[9]), v[10],
                        dict(v[11]) if len(v) > 11 else {}, v[12] if len(v) > 12 else None,
                        v[13] if len(v) > 13 else None)


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
    for i, (name, check, default) in enumerate(_APPENDED.get(kind, ()), start=2 + len(spec)):
        values.append(check(a[i], i, name, what) if i < len(a) else default)
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
    """Decode a rate payload; DecodeError names the bad field and value. Flags gain
    ``NON_FINITE`` when a rate, raw rate or bias value is NaN or ±inf."""
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
            # finite values sum to a finite number unless they overflow: then look closer
            s = a[5] + a[6] + a[7] + a[8] + a[9] + a[10] + a[11] + a[12] + a[13]
            if not s - s == 0.0 and not all(map(_isfinite, a[5:14])):
                flags |= _NON_FINITE
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
