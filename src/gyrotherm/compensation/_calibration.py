"""Calibrations: a fitted model with its contract, and the calibration file.

Contract (after PX4's ``TemperatureCompensation.h``):

* T is the gyro's internal temperature in °C, ΔT = T_env − T in °C from the
  estimator whose settings are stored here; the bias is in °/s and the
  corrected rate is ``raw − bias``.
* Coefficients are per axis, for the terms of the model, in the centred and
  scaled variables x = (T − t_ref_c)/t_scale_c, g = ΔT/dt_scale_c.
* Outside the calibrated ranges [t_min_c, t_max_c] and [dt_min_c, dt_max_c]
  the inputs are clamped to the range and a flag is raised: the model never
  extrapolates silently.

* Effects (version 2, :mod:`._calibration_v2`): per axis, the online kernel
  (:mod:`._effects`) gives the structure temperature the polynomial is
  evaluated at and an additive bias; :meth:`Calibration.compensator` holds one
  kernel per axis (:mod:`._compensator`).

File format: JSON, ``"schema": "gyrotherm.calibration"``, ``"version": 1`` (2 with
effects); docs/model.md lists every field. Written here (:meth:`Calibration.to_dict`,
:meth:`Calibration.save`), read by :mod:`._calibration_file`: a malformed, partial
or wrong-version file raises :class:`gyrotherm.CalibrationError` naming the file
and field.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._calibration_v2 import (
    RUNTIME_STATE,
    TIME_UNIT,
    VERSION_EFFECTS,
    effects_to_dict,
)
from gyrotherm.compensation._effects import Effects
from gyrotherm.compensation._models import ModelSpec, Scaling
from gyrotherm.estimators import EstimatorConfig

if TYPE_CHECKING:
    from gyrotherm.compensation._compensator import Compensator

FloatArray = NDArray[np.float64]
SCHEMA = "gyrotherm.calibration"
VERSION = 1
VERSIONS = (VERSION, VERSION_EFFECTS)
UNITS = {"temperature": "degC", "delta_t": "degC", "rate": "deg/s", "bias": "deg/s"}
#: Closed objects of a calibration file (dotted path, "" = top level) and their keys in
#: version 1: any other key is refused (:func:`_check_keys`), as in the TOML config.
#: Objects not listed are open (``provenance``) or checked where they are parsed
#: (``coefficients``: axes; ``estimator``: the EstimatorConfig fields).
KNOWN_KEYS: dict[str, tuple[str, ...]] = {
    "": ("schema", "version", "units", "model", "scaling", "coefficients",
         "coefficients_physical", "range", "estimator", "provenance"),
    "units": tuple(UNITS),
    "model": ("name", "terms"),
    "scaling": ("t_ref_c", "t_scale_c", "dt_scale_c"),
    "range": ("t_min_c", "t_max_c", "dt_min_c", "dt_max_c"),
    "coefficients_physical": ("x", "y", "z"),
}
#: Keys later versions add to :data:`KNOWN_KEYS`: ``{version: {path: keys}}``
#: (a new key is one line here).
KEYS_ADDED: dict[int, dict[str, tuple[str, ...]]] = {
    VERSION_EFFECTS: {"": ("effects", "runtime_state"), "units": (TIME_UNIT[0],)},
}


@dataclass(frozen=True)
class ValidRange:
    """Calibrated input ranges, °C."""

    t_min_c: float
    t_max_c: float
    dt_min_c: float
    dt_max_c: float

    def __post_init__(self) -> None:
        if not (self.t_min_c <= self.t_max_c and self.dt_min_c <= self.dt_max_c):
            raise CalibrationError(f"range: minimum above maximum in {self}")


@dataclass(frozen=True)
class BiasEstimate:
    """Bias per axis (°/s) at one (T, ΔT), with clamping flags."""

    bias_dps: Mapping[str, float]
    t_clamped: bool
    dt_clamped: bool
    flags: int = 0
    """:class:`~gyrotherm.compensation._effects_state.EffectFlags` of the effects kernels,
    merged over axes (:meth:`Compensator.step`; 0 from :meth:`Calibration.bias_at`)."""


SERIES_BLOCK_ROWS = 1 << 16
"""Rows evaluated at a time by :meth:`Calibration.base_series`."""


@dataclass(frozen=True)
class Calibration:
    """A fitted bias model for one gyro: coefficients, scaling, ranges, estimator."""

    model: ModelSpec
    scaling: Scaling
    coefficients: Mapping[str, tuple[float, ...]]
    valid_range: ValidRange
    estimator: EstimatorConfig
    provenance: Mapping[str, Any] = field(default_factory=dict)
    effects: Mapping[str, Effects] = field(default_factory=dict)
    """Per axis (absent: none); any effect makes the file version 2."""

    def __post_init__(self) -> None:
        extra = set(self.effects) - set(self.coefficients)
        if extra:
            raise CalibrationError(f"effects: axes {sorted(extra)} have no coefficients")
        k = len(self.model.terms)
        if not self.coefficients:
            raise CalibrationError("coefficients: no axis")
        for axis, c in self.coefficients.items():
            if axis not in ("x", "y", "z"):
                raise CalibrationError(f"coefficients: unknown axis {axis!r}")
            if len(c) != k or not all(math.isfinite(v) for v in c):
                raise CalibrationError(
                    f"coefficients.{axis}: expected {k} finite numbers for terms "
                    f"{list(self.model.term_names)}, got {list(c)!r}"
                )

    @property
    def axes(self) -> tuple[str, ...]:
        return tuple(a for a in ("x", "y", "z") if a in self.coefficients)

    @property
    def version(self) -> int:
        """File version written: 2 when any axis has effects, else 1."""
        return VERSION_EFFECTS if any(self.effect_names(a) for a in self.axes) else VERSION

    def effects_of(self, axis: str) -> Effects:
        return self.effects.get(axis, Effects())

    def effect_names(self, axis: str) -> tuple[str, ...]:
        return self.effects_of(axis).names

    def compensator(self) -> Compensator:
        """One online effects kernel per axis, from power-on (:mod:`._compensator`)."""
        from gyrotherm.compensation._compensator import Compensator

        return Compensator(self)

    def base_bias(self, axis: str, temperature_c: float, delta_t_c: float) -> float:
        """The polynomial of ``axis`` at one (T, ΔT), °C, as given (no clamping)."""
        x = (temperature_c - self.scaling.t_ref_c) / self.scaling.t_scale_c
        g = delta_t_c / self.scaling.dt_scale_c
        row = [x**term.t_power * g**term.dt_power for term in self.model.terms]
        return math.fsum(c * v for c, v in zip(self.coefficients[axis], row, strict=True))

    def base_series(self, axis: str, temperature_c: FloatArray, delta_t_c: FloatArray
                    ) -> FloatArray:
        """:meth:`base_bias` on arrays (equal to rounding), :data:`SERIES_BLOCK_ROWS`
        rows at a time (the design matrix of a long log is never formed whole)."""
        t, d = np.asarray(temperature_c), np.asarray(delta_t_c)
        coef = np.asarray(self.coefficients[axis], dtype=np.float64)
        if t.shape != d.shape or t.ndim != 1:  # scalars, broadcasting: no blocks
            x, g = self.scaling.centre(t, d)
            return np.asarray(self.model.design(x, g) @ coef, dtype=np.float64)
        bias = np.empty(len(t))
        for start in range(0, len(t), SERIES_BLOCK_ROWS):
            stop = start + SERIES_BLOCK_ROWS
            x, g = self.scaling.centre(t[start:stop], d[start:stop])
            bias[start:stop] = self.model.design(x, g) @ coef
        return bias

    def physical_coefficients(self, axis: str) -> dict[str, float]:
        """Coefficients of the model's terms in physical units (T, ΔT in °C)."""
        phys = self.scaling.to_physical(self.model, np.asarray(self.coefficients[axis]))
        return {t.name: phys[t] for t in self.model.terms}

    def clamp(
        self, temperature_c: FloatArray, delta_t_c: FloatArray
    ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_]]:
        """Clamp inputs to the calibrated range; return them and the clamp masks."""
        r = self.valid_range
        t = np.clip(temperature_c, r.t_min_c, r.t_max_c)
        d = np.clip(delta_t_c, r.dt_min_c, r.dt_max_c)
        return t, d, t != temperature_c, d != delta_t_c

    def bias_series(
        self, axis: str, temperature_c: FloatArray, delta_t_c: FloatArray,
        time_s: FloatArray | None = None,
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Bias (°/s) for arrays of T, ΔT (°C) and the mask of clamped rows.

        With effects on ``axis``, ``time_s`` (s since power-on, the run's time
        column) is required: the axis' kernel runs from the first row (its
        state starts there, t_on = ``time_s``), :meth:`Compensator.series`."""
        if self.effect_names(axis):
            if time_s is None:
                raise CalibrationError(f"axis {axis} has effects {list(self.effect_names(axis))}"
                                       ": its bias needs the time since power-on (time_s)")
            from gyrotherm.compensation._compensator import Compensator

            comp = Compensator(replace(self, coefficients={axis: self.coefficients[axis]},
                                       effects={axis: self.effects[axis]}))
            out = comp.series(np.asarray(time_s), np.asarray(temperature_c),
                              np.asarray(delta_t_c))
            return np.asarray(out.bias_dps[axis]), out.clamped(axis)
        t, d, tc, dc = self.clamp(np.asarray(temperature_c), np.asarray(delta_t_c))
        return self.base_series(axis, t, d), tc | dc

    def bias_at(self, temperature_c: float, delta_t_c: float) -> BiasEstimate:
        """Bias per axis at one point (the daemon calls this at the temperature rate).

        Only for calibrations without effects (version 1): effects need their
        history, :meth:`compensator` (whose step equals this one without effects)."""
        if self.version != VERSION:
            raise CalibrationError(
                "calibration has effects "
                f"{ {a: list(self.effect_names(a)) for a in self.axes} }: bias_at cannot "
                "evaluate them (they need their history); use Calibration.compensator()")
        r = self.valid_range
        t = min(max(temperature_c, r.t_min_c), r.t_max_c)
        d = min(max(delta_t_c, r.dt_min_c), r.dt_max_c)
        bias = {a: self.base_bias(a, t, d) for a in self.coefficients}
        return BiasEstimate(bias, t != temperature_c, d != delta_t_c)

    # --- file I/O -----------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        v2 = self.version == VERSION_EFFECTS
        out = {
            "schema": SCHEMA,
            "version": self.version,
            "units": dict([*UNITS.items(), TIME_UNIT]) if v2 else dict(UNITS),
            "model": {"name": self.model.name, "terms": list(self.model.term_names)},
            "scaling": {
                "t_ref_c": self.scaling.t_ref_c,
                "t_scale_c": self.scaling.t_scale_c,
                "dt_scale_c": self.scaling.dt_scale_c,
            },
            "coefficients": {a: list(c) for a, c in self.coefficients.items()},
            "coefficients_physical": {a: self.physical_coefficients(a) for a in self.axes},
            "range": {
                "t_min_c": self.valid_range.t_min_c,
                "t_max_c": self.valid_range.t_max_c,
                "dt_min_c": self.valid_range.dt_min_c,
                "dt_max_c": self.valid_range.dt_max_c,
            },
            "estimator": self.estimator.to_dict(),
            "provenance": dict(self.provenance),
        }
        if v2:
            out["effects"] = effects_to_dict(self.effects, self.axes)
            out["runtime_state"] = dict(RUNTIME_STATE)
        return out

    def save(self, path: str | Path) -> Path:
        """Write the calibration as JSON (atomically: temp file then rename).

        Raises :class:`CalibrationError` naming the path when it cannot be written."""
        p = Path(path)
        tmp = p.with_name(p.name + ".tmp")
        try:
            tmp.write_text(json.dumps(self.to_dict(), indent=2) + "\n", encoding="utf-8")
            tmp.replace(p)
        except OSError as exc:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
            raise CalibrationError(f"{p}: cannot write the calibration file ({exc})") from exc
        return p

    @classmethod
    def from_dict(cls, data: Any, *, source: str = "<memory>") -> Calibration:
        from gyrotherm.compensation._calibration_file import parse_data

        return parse_data(data, source)


def known_keys(version: int) -> dict[str, frozenset[str]]:
    """Keys of each closed object in a file of ``version``: :data:`KNOWN_KEYS` plus
    :data:`KEYS_ADDED` of every version up to ``version``."""
    known = {path: set(keys) for path, keys in KNOWN_KEYS.items()}
    for v, added in KEYS_ADDED.items():
        if v <= version:
            for path, keys in added.items():
                known.setdefault(path, set()).update(keys)
    return {path: frozenset(keys) for path, keys in known.items()}
