"""One units table for every imported column: unit name → linear conversion.

Every measurement role converts to one project unit: time to s, temperature to
°C, angular rate to °/s, acceleration to m/s². A unit is a pair
``(scale, offset)``: ``project_value = raw * scale + offset``.

====================  =================================================  ============
role                  units accepted (case-sensitive; aliases)            converts to
====================  =================================================  ============
time                  ``s``, ``ms``, ``us`` (``µs``), ``ns``              s
temperature           ``degC`` (``C``, ``°C``), ``mdegC`` (``mC``),       °C
                      ``cdegC``, ``K``, ``degF`` (``F``, ``°F``)
x, y, z (rate)        ``dps`` (``deg/s``, ``°/s``), ``mdps``,             °/s
                      ``rad/s`` (``rps``), ``mrad/s``
accel_x/y/z           ``m/s2`` (``m/s^2``, ``mps2``), ``g``, ``mg``       m/s²
====================  =================================================  ============

``g`` is the standard gravity 9.80665 m/s².
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

Kind = Literal["time", "temperature", "rate", "accel"]

STANDARD_GRAVITY_MPS2 = 9.80665
_DEG_PER_RAD = 180.0 / math.pi


@dataclass(frozen=True)
class Unit:
    """A unit of one kind: ``project_value = raw * scale + offset``."""

    name: str
    kind: Kind
    scale: float
    offset: float = 0.0


def _units(kind: Kind, table: dict[str, tuple[float, float]]) -> dict[str, Unit]:
    return {name: Unit(name, kind, s, o) for name, (s, o) in table.items()}


UNITS: dict[Kind, dict[str, Unit]] = {
    "time": _units("time", {"s": (1.0, 0.0), "ms": (1e-3, 0.0), "us": (1e-6, 0.0),
                            "µs": (1e-6, 0.0), "ns": (1e-9, 0.0)}),
    "temperature": _units("temperature", {
        "degC": (1.0, 0.0), "C": (1.0, 0.0), "°C": (1.0, 0.0),
        "mdegC": (1e-3, 0.0), "mC": (1e-3, 0.0), "cdegC": (1e-2, 0.0),
        "K": (1.0, -273.15),
        "degF": (5.0 / 9.0, -32.0 * 5.0 / 9.0), "F": (5.0 / 9.0, -32.0 * 5.0 / 9.0),
        "°F": (5.0 / 9.0, -32.0 * 5.0 / 9.0)}),
    "rate": _units("rate", {
        "dps": (1.0, 0.0), "deg/s": (1.0, 0.0), "°/s": (1.0, 0.0), "mdps": (1e-3, 0.0),
        "rad/s": (_DEG_PER_RAD, 0.0), "rps": (_DEG_PER_RAD, 0.0),
        "mrad/s": (_DEG_PER_RAD * 1e-3, 0.0)}),
    "accel": _units("accel", {
        "m/s2": (1.0, 0.0), "m/s^2": (1.0, 0.0), "mps2": (1.0, 0.0),
        "g": (STANDARD_GRAVITY_MPS2, 0.0), "mg": (STANDARD_GRAVITY_MPS2 * 1e-3, 0.0)}),
}
"""Units accepted per kind (see the module docstring)."""

PROJECT_UNIT: dict[Kind, str] = {"time": "s", "temperature": "degC", "rate": "dps",
                                 "accel": "m/s2"}
"""The unit each kind is converted to."""


def unit_names(kind: Kind) -> str:
    """The accepted unit names of ``kind``, comma separated (for error messages)."""
    return ", ".join(UNITS[kind])
