"""Write tests/vectors/wire-v1.json: language-neutral test vectors of every wire message.

Usage: ``python scripts/make_vectors.py [--out tests/vectors/wire-v1.json] [--check]``.

Deterministic (fixed values, no clock, no random): running it twice gives the same
file, and ``--check`` exits 1 when the committed file differs from what the real
encoders (:mod:`gyrotherm.codecs._wire`) produce now.

Each vector has the key suffix it is published on, the message kind and schema
version, the complete payload as lower-case hex, and the decoded fields in wire
order with their names, units and values (JSON numbers; ``null`` for nil; the
strings ``"NaN"``, ``"Infinity"``, ``"-Infinity"`` for those floats). Vectors
with ``"direction": "decode"`` are payloads of an older publisher (fields appended
later within schema 1 absent) that today's encoder no longer produces: a decoder
must accept them and fill the documented default. See docs/wire-format.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import msgpack

from gyrotherm.codecs._wire import (
    SCHEMA_VERSION,
    AxisEffects,
    CalibrationInfo,
    HealthMessage,
    RateMessage,
    StateMessage,
    StatusFlags,
    ZeroState,
    encode_calibration_info,
    encode_health,
    encode_rate,
    encode_state,
)

OUT = Path(__file__).resolve().parents[1] / "tests" / "vectors" / "wire-v1.json"

_EFFECT_FIELDS = ("structure_temperature_c", "hysteresis_h", "hysteresis_direction",
                  "t_on_s", "effects_bias_dps")  # fmt: skip

UNITS: dict[str, str] = {
    "kind": "-", "version": "-", "seq": "-", "sensor_time_s": "s", "receive_time_s": "s",
    "rate_dps": "deg/s", "raw_rate_dps": "deg/s", "bias_dps": "deg/s",
    "temperature_c": "degC", "temperature_std_c": "degC", "delta_t_c": "degC",
    "delta_t_std_c": "degC", "flags": "-", "effects": "per axis: [degC, -, -, s, deg/s]",
    "zero": "[status (0 off, 1 pending, 2 done, 3 failed), deg/s x3]",
    "uptime_s": "s", "frames_received": "frames", "frames_published": "frames",
    "drops": "frames", "calibration_id": "-", "counter_jumps": "events",
    "calibration": "as in the calibration file", "health": "health fields",
}  # fmt: skip

RATE = RateMessage(7, 12.5, 1700000000.25, (0.75, -2.5, 0.25), (1.0, -2.25, 0.375),
                   (0.25, 0.25, 0.125), StatusFlags.NONE)  # fmt: skip
RATE_FLAGGED = RateMessage(70000, 3600.0, 1700003600.5, (0.0, 0.0, 0.0), (0.002, -0.004, 0.0),
                           (0.0, 0.0, 0.0),
                           StatusFlags.NO_CALIBRATION | StatusFlags.TEMPERATURE_STALE)  # fmt: skip
STATE = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                     StatusFlags.ESTIMATOR_WARMUP)  # fmt: skip
STATE_EFFECTS = StateMessage(3, 10.0, 11.0, 25.5, 0.125, -1.5, 0.0625, (1.0, 2.0, 3.0),
                             StatusFlags.T_ON_CLAMPED | StatusFlags.ESTIMATOR_WARMUP,
                             {"x": AxisEffects(31.25, -0.5, -1, 600.0, 0.0125),
                              "y": AxisEffects(25.5, 0.0, 0, 600.0, 0.0),
                              "z": AxisEffects(27.0, 1.0, 1, 600.0, -0.25)})  # fmt: skip
STATE_ZERO = StateMessage(90, 60.0, 1700000060.0, 26.25, 0.0625, 0.125, 0.03125,
                          (0.5, -0.25, 0.125), StatusFlags.NONE, {},
                          ZeroState(2, (0.0125, -0.03125, 0.0078125)))  # fmt: skip
STATE_ZERO_PENDING = StateMessage(4, 5.0, 1700000005.0, 26.25, 0.0625, 0.0, 0.03125,
                                  (0.5, -0.25, 0.125), StatusFlags.ZERO_PENDING,
                                  {"x": AxisEffects(26.25, 0.0, 0, 5.0, 0.0)},
                                  ZeroState(1, (0.0, 0.0, 0.0)))  # fmt: skip
NAN = float("nan")
STATE_NAN = StateMessage(0, 0.5, 1700000000.5, NAN, NAN, NAN, NAN, (0.0, 0.0, 0.0),
                         StatusFlags.TEMPERATURE_STALE | StatusFlags.ESTIMATOR_WARMUP)
HEALTH = HealthMessage(41, 40.5, 1700000041.0, 42.0, 1205, 1200,
                       {"crc_mismatch": 3, "no_subscriber": 2}, StatusFlags.NONE, "cal-7f3a", 1)
HEALTH_EMPTY = HealthMessage(0, None, 1700000000.0, 0.5, 0, 0, {}, StatusFlags.NO_CALIBRATION,
                             "", 0)  # fmt: skip
CALIBRATION = CalibrationInfo(
    "cal-7f3a",
    {"format": "gyrotherm-calibration", "version": 1, "model": "paper",
     "axes": {"x": {"coefficients": [0.00012, -0.01, 0.05, -0.0004, 0.3]}}},
    HEALTH,
)  # fmt: skip
CALIBRATION_NONE = CalibrationInfo("", None, None)


def _plain(v: Any) -> Any:
    """JSON value of a decoded field (tuples → lists, enums → int, effects → objects;
    NaN, ±inf → the strings "NaN", "Infinity", "-Infinity": JSON has no such numbers)."""
    if isinstance(v, float) and not math.isfinite(v):
        return "NaN" if math.isnan(v) else ("Infinity" if v > 0 else "-Infinity")
    if isinstance(v, StatusFlags):
        return int(v)
    if isinstance(v, AxisEffects):
        return dict(zip(_EFFECT_FIELDS, v, strict=True))
    if isinstance(v, ZeroState):
        return {"status": v.status, "offset_dps": list(v.offset_dps)}
    if isinstance(v, HealthMessage):
        return _fields("health", v)
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    if isinstance(v, dict) or hasattr(v, "items"):
        return {str(k): _plain(x) for k, x in v.items()}
    return v


_ORDER = {
    "rate": ("seq", "sensor_time_s", "receive_time_s", "rate_dps", "raw_rate_dps", "bias_dps",
             "flags"),
    "state": ("seq", "sensor_time_s", "receive_time_s", "temperature_c", "temperature_std_c",
              "delta_t_c", "delta_t_std_c", "bias_dps", "flags", "effects", "zero"),
    "health": ("seq", "sensor_time_s", "receive_time_s", "uptime_s", "frames_received",
               "frames_published", "drops", "flags", "calibration_id", "counter_jumps"),
    "calibration": ("calibration_id", "calibration", "health"),
}  # fmt: skip
_KINDS = {"rate": 1, "state": 2, "health": 3, "calibration": 4}


def _fields(kind: str, msg: Any, *, drop: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    out = [{"name": "kind", "unit": "-", "value": _KINDS[kind]},
           {"name": "version", "unit": "-", "value": SCHEMA_VERSION}]  # fmt: skip
    for name in _ORDER[kind]:
        if name in drop:
            continue
        if kind == "state" and name == "effects" and not msg.effects and msg.zero is None:
            continue  # the encoder appends it only when not empty, or before a zero
        if kind == "state" and name == "zero" and msg.zero is None:
            continue
        out.append({"name": name, "unit": UNITS[name], "value": _plain(getattr(msg, name))})
    return out


def _vector(name: str, kind: str, key: str, payload: bytes, fields: list[dict[str, Any]],
            note: str, *, direction: str = "both") -> dict[str, Any]:  # fmt: skip
    return {"name": name, "key": f"gyrotherm/<vehicle>/<sensor>/{key}", "kind": kind,
            "schema_version": SCHEMA_VERSION, "direction": direction, "note": note,
            "length": len(payload), "hex": payload.hex(), "fields": fields}  # fmt: skip


def build() -> dict[str, Any]:
    # An older publisher's health message: 11 elements, no counter_jumps (decoders give 0).
    old_health = msgpack.packb(msgpack.unpackb(encode_health(HEALTH))[:11])
    old_fields = _fields("health", HEALTH, drop=("counter_jumps",))
    vectors = [
        _vector("rate", "rate", "rate", encode_rate(RATE), _fields("rate", RATE),
                "one corrected sample: rate = raw - bias per axis"),
        _vector("rate-flagged-seq32", "rate", "rate", encode_rate(RATE_FLAGGED),
                _fields("rate", RATE_FLAGGED),
                "seq >= 65536 (uint 32), flags NO_CALIBRATION|TEMPERATURE_STALE"),
        _vector("state", "state", "state", encode_state(STATE), _fields("state", STATE),
                "without effects (13 elements): no compensator running, or an older publisher"),
        _vector("state-not-available", "state", "state", encode_state(STATE_NAN),
                _fields("state", STATE_NAN),
                "before the first temperature frame: NaN (\"not available\") as float 64 "
                "7ff8000000000000; JSON writes it as the string \"NaN\""),
        _vector("state-effects", "state", "state", encode_state(STATE_EFFECTS),
                _fields("state", STATE_EFFECTS), "with the appended effects element (14)"),
        _vector("state-zero-done", "state", "state", encode_state(STATE_ZERO),
                _fields("state", STATE_ZERO),
                "boot-time zero done (15 elements): effects written empty ({}) before it; "
                "the offsets are part of bias_dps"),
        _vector("state-zero-pending", "state", "state", encode_state(STATE_ZERO_PENDING),
                _fields("state", STATE_ZERO_PENDING),
                "boot-time zero pending (flag ZERO_PENDING), with effects"),
        _vector("health", "health", "health", encode_health(HEALTH), _fields("health", HEALTH),
                "with drops, calibration id and counter_jumps"),
        _vector("health-before-first-frame", "health", "health", encode_health(HEALTH_EMPTY),
                _fields("health", HEALTH_EMPTY), "sensor_time_s nil, no drops, no calibration"),
        _vector("health-without-counter-jumps", "health", "health", old_health, old_fields,
                "older publisher (11 elements): decoders give counter_jumps = 0",
                direction="decode"),
        _vector("calibration", "calibration", "calibration (query reply)",
                encode_calibration_info(CALIBRATION), _fields("calibration", CALIBRATION),
                "reply of the calibration queryable: id, calibration map, health array"),
        _vector("calibration-none", "calibration", "calibration (query reply)",
                encode_calibration_info(CALIBRATION_NONE), _fields("calibration", CALIBRATION_NONE),
                "no calibration loaded, no health yet"),
    ]
    return {
        "format": "gyrotherm-wire-vectors",
        "schema_version": SCHEMA_VERSION,
        "generated_by": "scripts/make_vectors.py (gyrotherm.codecs._wire encoders)",
        "encoding": "msgpack array per message; floats as float 64 (0xcb), see docs/wire-format.md",
        "units": "deg/s = degrees per second (ROS uses rad/s: multiply by pi/180); degC; s",
        "flags": {f.name: int(f) for f in StatusFlags if f and f.name},
        "vectors": vectors,
    }


def render() -> str:
    return json.dumps(build(), indent=1, ensure_ascii=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--check", action="store_true", help="exit 1 when --out differs")
    args = p.parse_args(argv)
    text = render()
    if args.check:
        same = args.out.exists() and args.out.read_text(encoding="utf-8") == text
        print(f"{args.out}: {'up to date' if same else 'DIFFERS from the encoders'}")
        return 0 if same else 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    print(f"wrote {args.out} ({len(build()['vectors'])} vectors)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
