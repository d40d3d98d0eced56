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

File format: JSON, ``"schema": "gyrotherm.calibration"``, ``"version": 1``;
docs/model.md lists every field. A malformed, partial or wrong-version file
raises :class:`gyrotherm.CalibrationError` naming the file and field.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.compensation._models import ModelSpec, Scaling, Term, get_model
from gyrotherm.estimators import EstimatorConfig

FloatArray = NDArray[np.float64]
SCHEMA = "gyrotherm.calibration"
VERSION = 1
UNITS = {"temperature": "degC", "delta_t": "degC", "rate": "deg/s", "bias": "deg/s"}


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


@dataclass(frozen=True)
class Calibration:
    """A fitted bias model for one gyro: coefficients, scaling, ranges, estimator."""

    model: ModelSpec
    scaling: Scaling
    coefficients: Mapping[str, tuple[float, ...]]
    valid_range: ValidRange
    estimator: EstimatorConfig
    provenance: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
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
        self, axis: str, temperature_c: FloatArray, delta_t_c: FloatArray
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Bias (°/s) for arrays of T, ΔT (°C) and the mask of clamped rows."""
        t, d, tc, dc = self.clamp(np.asarray(temperature_c), np.asarray(delta_t_c))
        x, g = self.scaling.centre(t, d)
        design = self.model.design(x, g)
        bias = design @ np.asarray(self.coefficients[axis])
        return np.asarray(bias, dtype=np.float64), tc | dc

    def bias_at(self, temperature_c: float, delta_t_c: float) -> BiasEstimate:
        """Bias per axis at one point (the daemon calls this at the temperature rate)."""
        r = self.valid_range
        t = min(max(temperature_c, r.t_min_c), r.t_max_c)
        d = min(max(delta_t_c, r.dt_min_c), r.dt_max_c)
        x = (t - self.scaling.t_ref_c) / self.scaling.t_scale_c
        g = d / self.scaling.dt_scale_c
        row = [x**term.t_power * g**term.dt_power for term in self.model.terms]
        bias = {a: math.fsum(c * v for c, v in zip(cs, row, strict=True))
                for a, cs in self.coefficients.items()}
        return BiasEstimate(bias, t != temperature_c, d != delta_t_c)

    # --- file I/O -----------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "version": VERSION,
            "units": dict(UNITS),
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
        return _parse(data, source)


def load_calibration(path: str | Path) -> Calibration:
    """Read and validate a calibration file; CalibrationError names file and field."""
    return read_calibration(path)[0]


def read_calibration(path: str | Path) -> tuple[Calibration, str]:
    """The calibration in ``path`` and its id: the first 16 hex digits of the sha256
    of the very bytes parsed (so the id always names the content loaded)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise CalibrationError(f"{p}: cannot read calibration file: {exc}") from exc
    return parse_calibration(raw, source=str(p)), hashlib.sha256(raw).hexdigest()[:16]


def parse_calibration(raw: bytes | str, *, source: str = "<memory>") -> Calibration:
    """Validate calibration JSON text; CalibrationError names ``source`` and the field."""
    try:
        text = raw.decode("utf-8") if isinstance(raw, bytes) else raw
        data = json.loads(text)
    except UnicodeDecodeError as exc:
        raise CalibrationError(f"{source}: not UTF-8 text (byte {exc.start})") from exc
    except json.JSONDecodeError as exc:
        raise CalibrationError(
            f"{source}: line {exc.lineno}: not valid JSON ({exc.msg})"
        ) from exc
    except (RecursionError, ValueError) as exc:  # absurd nesting, huge integers
        raise CalibrationError(f"{source}: unreadable JSON ({exc})") from exc
    return _parse(data, source)


def _get(data: Any, path: str, kind: type | tuple[type, ...], source: str) -> Any:
    node = data
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            raise CalibrationError(f"{source}: missing field {path!r}")
        node = node[key]
    if not isinstance(node, kind) or (isinstance(node, bool) and kind is not bool):
        want = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise CalibrationError(f"{source}: field {path!r}: expected {want}, got {node!r}")
    return node


def _num(data: Any, path: str, source: str) -> float:
    return _value(_get(data, path, (int, float), source), path, source)


def _value(node: Any, path: str, source: str) -> float:
    """``node`` as a finite float; CalibrationError naming ``path`` otherwise."""
    if not isinstance(node, int | float) or isinstance(node, bool):
        raise CalibrationError(f"{source}: field {path!r}: expected a number, got {node!r}")
    try:
        v = float(node)
    except OverflowError:
        raise CalibrationError(f"{source}: field {path!r}: number too large") from None
    if not math.isfinite(v):
        raise CalibrationError(f"{source}: field {path!r}: not a finite number ({v!r})")
    return v


def _parse(data: Any, source: str) -> Calibration:
    if not isinstance(data, dict):
        raise CalibrationError(f"{source}: expected a JSON object at top level")
    schema = _get(data, "schema", str, source)
    if schema != SCHEMA:
        raise CalibrationError(f"{source}: field 'schema': expected {SCHEMA!r}, got {schema!r}")
    version = _get(data, "version", int, source)
    if version != VERSION:
        raise CalibrationError(
            f"{source}: field 'version': unsupported calibration version {version} "
            f"(this gyrotherm reads version {VERSION})"
        )
    units = _get(data, "units", dict, source)
    for key, unit in UNITS.items():
        if units.get(key) != unit:
            raise CalibrationError(
                f"{source}: field 'units.{key}': expected {unit!r}, got {units.get(key)!r}"
            )
    try:
        model = get_model(_get(data, "model.name", str, source))
    except CalibrationError as exc:
        raise CalibrationError(f"{source}: field 'model.name': {exc}") from exc
    terms = _get(data, "model.terms", list, source)
    try:
        parsed = [Term.parse(str(t)) for t in terms]
    except CalibrationError as exc:
        raise CalibrationError(f"{source}: field 'model.terms': {exc}") from exc
    if parsed != list(model.terms):
        raise CalibrationError(
            f"{source}: field 'model.terms': {terms!r} do not match model "
            f"{model.name!r} terms {list(model.term_names)!r}"
        )
    raw_coeffs = _get(data, "coefficients", dict, source)
    coefficients: dict[str, tuple[float, ...]] = {}
    for axis in raw_coeffs:
        vals = _get(data, f"coefficients.{axis}", list, source)
        coefficients[axis] = tuple(_value(v, f"coefficients.{axis}[{k}]", source)
                                   for k, v in enumerate(vals))
    try:
        estimator = EstimatorConfig.from_dict(
            _get(data, "estimator", dict, source), where=f"{source}: field 'estimator'"
        )
        cal = Calibration(
            model=model,
            scaling=Scaling(*(_num(data, f"scaling.{k}", source)
                              for k in ("t_ref_c", "t_scale_c", "dt_scale_c"))),
            coefficients=coefficients,
            valid_range=ValidRange(*(_num(data, f"range.{k}", source)
                                     for k in ("t_min_c", "t_max_c", "dt_min_c", "dt_max_c"))),
            estimator=estimator,
            provenance=_get(data, "provenance", dict, source),
        )
        _check_physical(data, cal, source)
        return cal
    except ConfigError as exc:
        msg = str(exc)
        raise CalibrationError(msg if msg.startswith(source) else f"{source}: {msg}") from exc
    except CalibrationError as exc:
        if str(exc).startswith(source):
            raise
        raise CalibrationError(f"{source}: {exc}") from exc


def _check_physical(data: dict[str, Any], cal: Calibration, source: str) -> None:
    """``coefficients_physical`` (optional, informative) must agree with the centred
    ``coefficients`` that are evaluated: an edit of the physical ones would
    otherwise be silently ignored."""
    phys = data.get("coefficients_physical")
    if phys is None:
        return
    if not isinstance(phys, dict):
        raise CalibrationError(f"{source}: field 'coefficients_physical': expected an object")
    for axis in cal.axes:
        want = cal.physical_coefficients(axis)
        got = phys.get(axis)
        if not isinstance(got, dict) or set(got) != set(want):
            raise CalibrationError(
                f"{source}: field 'coefficients_physical.{axis}': expected terms "
                f"{sorted(want)}, got {got!r}"
            )
        scale = max(abs(v) for v in want.values()) or 1.0
        for term, value in want.items():
            path = f"coefficients_physical.{axis}.{term}"
            stored = _value(got[term], path, source)
            if not math.isclose(stored, value, rel_tol=1e-9, abs_tol=1e-12 * scale):
                raise CalibrationError(
                    f"{source}: field {path!r} = {stored!r} disagrees with "
                    f"'coefficients.{axis}' ({value!r} in physical units): the centred "
                    "'coefficients' are what is evaluated; refit, or delete "
                    "'coefficients_physical'"
                )
