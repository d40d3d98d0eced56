"""tests/vectors/wire-v1.json: the language-neutral vectors, both ways.

decode(hex) with the client's decoder gives the listed fields; the daemon's
encoder given the listed values gives the hex; a plain msgpack unpack (no
gyrotherm code) gives the listed values in wire order; the file is what
scripts/make_vectors.py writes now; docs/wire-format.md shows one vector whole.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import msgpack
import pytest

from gyrotherm.codecs._wire import (
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
from gyrotherm.codecs._wire_decode import decode_message

ROOT = Path(__file__).resolve().parents[2]
VECTORS = json.loads((ROOT / "tests" / "vectors" / "wire-v1.json").read_text(encoding="utf-8"))
ALL = VECTORS["vectors"]


_SPECIAL = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _num(x: Any) -> Any:
    """JSON value → wire value: the strings for non-finite floats back to floats."""
    if isinstance(x, str) and x in _SPECIAL:
        return _SPECIAL[x]
    if isinstance(x, list):
        return [_num(y) for y in x]
    if isinstance(x, dict):
        return {k: _num(y) for k, y in x.items()}
    return x


def _json(x: Any) -> Any:
    """Wire value → JSON value (non-finite floats as the strings the file uses)."""
    if isinstance(x, float) and not math.isfinite(x):
        return "NaN" if math.isnan(x) else ("Infinity" if x > 0 else "-Infinity")
    if isinstance(x, list):
        return [_json(y) for y in x]
    if isinstance(x, dict):
        return {k: _json(y) for k, y in x.items()}
    return x


def _values(v: dict[str, Any]) -> dict[str, Any]:
    return {f["name"]: _num(f["value"]) for f in v["fields"]}


def _health(f: dict[str, Any]) -> HealthMessage:
    return HealthMessage(f["seq"], f["sensor_time_s"], f["receive_time_s"], f["uptime_s"],
                         f["frames_received"], f["frames_published"], f["drops"],
                         StatusFlags(f["flags"]), f["calibration_id"],
                         f.get("counter_jumps", 0))  # fmt: skip


def _health_values(fields: list[dict[str, Any]]) -> dict[str, Any]:
    return {f["name"]: _num(f["value"]) for f in fields}


def message_from_json(v: dict[str, Any]) -> Any:
    """The typed message a vector's fields describe (documented defaults for absent ones)."""
    f = _values(v)
    if v["kind"] == "rate":
        return RateMessage(f["seq"], f["sensor_time_s"], f["receive_time_s"],
                           tuple(f["rate_dps"]), tuple(f["raw_rate_dps"]), tuple(f["bias_dps"]),
                           StatusFlags(f["flags"]))  # fmt: skip
    if v["kind"] == "state":
        eff = {a: AxisEffects(e["structure_temperature_c"], e["hysteresis_h"],
                              e["hysteresis_direction"], e["t_on_s"], e["effects_bias_dps"])
               for a, e in f.get("effects", {}).items()}  # fmt: skip
        z = f.get("zero")
        zero = None if z is None else ZeroState(z["status"], tuple(z["offset_dps"]))
        return StateMessage(f["seq"], f["sensor_time_s"], f["receive_time_s"], f["temperature_c"],
                            f["temperature_std_c"], f["delta_t_c"], f["delta_t_std_c"],
                            tuple(f["bias_dps"]), StatusFlags(f["flags"]), eff,
                            zero)  # fmt: skip
    if v["kind"] == "health":
        return _health(f)
    h = f["health"]
    return CalibrationInfo(f["calibration_id"], f["calibration"],
                           None if h is None else _health(_health_values(h)))


ENCODE = {"rate": encode_rate, "state": encode_state, "health": encode_health,
          "calibration": encode_calibration_info}  # fmt: skip


@pytest.mark.parametrize("v", ALL, ids=[v["name"] for v in ALL])
def test_decode_of_the_bytes_is_the_listed_values(v: dict[str, Any]) -> None:
    payload = bytes.fromhex(v["hex"])
    assert len(payload) == v["length"]
    # repr: exact for floats (shortest round-trip form) and equal for NaN, unlike ==
    assert repr(decode_message(payload)) == repr(message_from_json(v))


@pytest.mark.parametrize("v", [v for v in ALL if v["direction"] == "both"],
                         ids=[v["name"] for v in ALL if v["direction"] == "both"])  # fmt: skip
def test_encode_of_the_values_is_the_bytes(v: dict[str, Any]) -> None:
    assert ENCODE[v["kind"]](message_from_json(v)).hex() == v["hex"]


def _wire_order(fields: list[dict[str, Any]]) -> list[Any]:
    """The msgpack array a vector's fields make, vectors spread over 3 elements."""
    out: list[Any] = []
    for f in fields:
        val = f["value"]
        if f["name"] in ("rate_dps", "raw_rate_dps", "bias_dps"):
            out.extend(val)
        elif f["name"] == "effects":
            out.append({a: list(e.values()) for a, e in val.items()})
        elif f["name"] == "zero":
            out.append([val["status"], *val["offset_dps"]])
        elif f["name"] == "health" and val is not None:
            out.append(_wire_order(val))
        else:
            out.append(val)
    return out


@pytest.mark.parametrize("v", ALL, ids=[v["name"] for v in ALL])
def test_a_plain_msgpack_unpack_gives_the_fields_in_order(v: dict[str, Any]) -> None:
    """What a consumer in another language sees: just msgpack, no gyrotherm code."""
    assert _json(msgpack.unpackb(bytes.fromhex(v["hex"]))) == _wire_order(v["fields"])


def test_every_kind_and_both_state_forms_are_covered() -> None:
    names = {v["name"] for v in ALL}
    assert {v["kind"] for v in ALL} == {"rate", "state", "health", "calibration"}
    assert {"state", "state-effects", "state-not-available", "state-zero-done",
            "state-zero-pending"} <= names
    assert {f["name"] for f in next(v for v in ALL if v["name"] == "state-effects")["fields"]} \
        >= {"effects"}


def test_the_file_is_what_the_generator_writes_now() -> None:
    out = subprocess.run([sys.executable, str(ROOT / "scripts" / "make_vectors.py"), "--check"],
                         capture_output=True, text=True, check=False)  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_docs_show_the_rate_vector_whole() -> None:
    text = (ROOT / "docs" / "wire-format.md").read_text(encoding="utf-8")
    m = re.search(r"rate-vector:\s*\n```\n([0-9a-f\n]+)```", text)
    assert m, "docs/wire-format.md lacks the rate-vector block"
    rate = next(v for v in ALL if v["name"] == "rate")
    assert m.group(1).replace("\n", "") == rate["hex"]
