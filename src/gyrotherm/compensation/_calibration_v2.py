"""Calibration file version 2: per-axis effects and the runtime-state declaration.

Version 2 is version 1 plus (docs/model.md §6):

* ``units.time``: ``"s"`` (t, t_on, time constants);
* ``effects.<axis>.<effect>.<parameter>``: every axis of ``coefficients``, each
  an object (empty: the paper polynomial alone) of effects in
  :meth:`~gyrotherm.compensation._effects.Effects.to_params` layout, e.g.
  ``{"hysteresis": {"amplitude_dps": 0.05, "transition_c": 0.4}}``; the
  ``correction`` effect (:mod:`~gyrotherm.compensation._correction`) is
  ``{"variable": "temperature_c", "knots": [...], "values_dps": [...],
  "source": "..."}`` (a linear spline, constant beyond its first and last knot);
* ``runtime_state``: ``{"version": 1, "per": "axis", "fields": [...]}``, the
  layout of :class:`~gyrotherm.compensation._effects_state.EffectsState` the
  effects need at run time (one per axis, starting at power-on).

A file without effects is written as version 1, so plain paper/t2/t3 fits
stay byte-compatible with readers of version 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import MISSING, fields
from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._correction import Correction
from gyrotherm.compensation._effects import _KINDS, Effects
from gyrotherm.compensation._effects_state import STATE_VERSION, EffectsState

VERSION_EFFECTS = 2
TIME_UNIT = ("time", "s")
STATE_FIELDS = tuple(f.name for f in fields(EffectsState))
RUNTIME_STATE: dict[str, Any] = {"version": STATE_VERSION, "per": "axis",
                                 "fields": list(STATE_FIELDS)}


def effects_to_dict(effects: Mapping[str, Effects], axes: tuple[str, ...]) -> dict[str, Any]:
    """``effects`` block: every axis, ``{}`` for an axis without effects."""
    return {a: effects[a].to_params() if a in effects else {} for a in axes}


def finite_number(node: Any, path: str, source: str) -> float:
    """``node`` as a finite float; CalibrationError naming ``source`` and ``path`` otherwise
    (shared by both file versions' readers)."""
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise CalibrationError(f"{source}: field {path!r}: expected a number, got {node!r}")
    try:
        v = float(node)
    except OverflowError:
        raise CalibrationError(f"{source}: field {path!r}: number too large") from None
    if not math.isfinite(v):
        raise CalibrationError(f"{source}: field {path!r}: not a finite number ({v!r})")
    return v


def parse_effects(node: Any, axes: tuple[str, ...], source: str) -> dict[str, Effects]:
    """Validate the ``effects`` block; CalibrationError names ``source`` and the field."""
    if not isinstance(node, dict):
        raise CalibrationError(f"{source}: field 'effects': expected an object, got {node!r:.60}")
    if set(node) != set(axes):
        raise CalibrationError(f"{source}: field 'effects': expected the axes of "
                               f"'coefficients' {list(axes)}, got {sorted(node)}")
    out: dict[str, Effects] = {}
    for axis in axes:
        per_axis = node[axis]
        if not isinstance(per_axis, dict):
            raise CalibrationError(f"{source}: field 'effects.{axis}': expected an object, "
                                   f"got {per_axis!r:.60}")
        params: dict[str, dict[str, Any]] = {}
        for name, values in per_axis.items():
            path = f"effects.{axis}.{name}"
            params[name] = (_parse_correction(values, path, source) if name == "correction"
                            else _parse_effect(values, path, name, source))
        effects = Effects.from_params(params)
        if effects.names:
            out[axis] = effects
    return out


def _parse_effect(values: Any, path: str, name: str, source: str) -> dict[str, float | None]:
    kind = _KINDS.get(name)
    if kind is None:
        raise CalibrationError(f"{source}: field {path!r}: unknown effect; known: "
                               f"{', '.join(_KINDS)}")
    if not isinstance(values, dict):
        raise CalibrationError(f"{source}: field {path!r}: expected an object, "
                               f"got {values!r:.60}")
    known = {f.name: f.default is MISSING for f in fields(kind)}
    extra = sorted(set(values) - set(known))
    if extra:
        raise CalibrationError(f"{source}: field '{path}.{extra[0]}': unknown parameter; "
                               f"{name} has {list(known)}")
    positive: tuple[str, ...] = getattr(kind, "_positive", ())
    out: dict[str, float | None] = {}
    for key, required in known.items():
        where = f"{path}.{key}"
        if key not in values:
            if required:
                raise CalibrationError(f"{source}: missing field {where!r}")
            continue
        if values[key] is None and not required:
            out[key] = None
            continue
        v = finite_number(values[key], where, source)
        if key in positive and not v > 0.0:
            raise CalibrationError(f"{source}: field {where!r}: must be > 0, got {v!r}")
        out[key] = v
    return out


def _parse_correction(values: Any, path: str, source: str) -> dict[str, Any]:
    """The ``correction`` block, checked by :class:`Correction` (errors name the field)."""
    if not isinstance(values, dict):
        raise CalibrationError(f"{source}: field {path!r}: expected an object, "
                               f"got {values!r:.60}")
    known = ("variable", "knots", "values_dps", "source")
    extra = sorted(set(values) - set(known))
    if extra:
        raise CalibrationError(f"{source}: field '{path}.{extra[0]}': unknown parameter; "
                               f"correction has {list(known)}")
    for key in known[:3]:
        if key not in values:
            raise CalibrationError(f"{source}: missing field '{path}.{key}'")
    try:
        Correction(**values)
    except CalibrationError as exc:
        raise CalibrationError(f"{source}: field {path!r}: {exc}") from exc
    except TypeError as exc:  # a variable that is not text, and the like
        raise CalibrationError(f"{source}: field {path!r}: {exc}") from exc
    return dict(values)


def parse_runtime_state(node: Any, source: str) -> None:
    """The ``runtime_state`` declaration must name the state this gyrotherm keeps."""
    if node != RUNTIME_STATE:
        raise CalibrationError(
            f"{source}: field 'runtime_state': expected {RUNTIME_STATE!r} (effects state "
            f"version {STATE_VERSION}), got {node!r:.200}")
