"""Reading calibration files: JSON text → validated :class:`Calibration`.

Every error is a :class:`gyrotherm.CalibrationError` naming the file (``source``)
and the field; closed objects refuse unknown keys (:data:`KNOWN_KEYS` and
:data:`KEYS_ADDED` in :mod:`._calibration`, per version); version 2's effects
and runtime-state blocks are checked by :mod:`._calibration_v2`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm._safefile import decode_utf8, parse_json, read_bounded
from gyrotherm.compensation._calibration import (
    SCHEMA,
    UNITS,
    VERSIONS,
    Calibration,
    ValidRange,
    known_keys,
)
from gyrotherm.compensation._calibration_v2 import (
    TIME_UNIT,
    VERSION_EFFECTS,
    parse_effects,
    parse_runtime_state,
)
from gyrotherm.compensation._calibration_v2 import (
    finite_number as _value,
)
from gyrotherm.compensation._models import Scaling, Term, get_model
from gyrotherm.compensation._plausibility import check_plausible
from gyrotherm.estimators import EstimatorConfig

#: Largest calibration file read, bytes (a calibration is a few kB).
MAX_CALIBRATION_BYTES = 1 << 20


def load_calibration(path: str | Path) -> Calibration:
    """Read and validate a calibration file; CalibrationError names file and field."""
    return read_calibration(path)[0]


def read_calibration(path: str | Path) -> tuple[Calibration, str]:
    """The calibration in ``path`` and its id: the first 16 hex digits of the sha256
    of the very bytes parsed (so the id always names the content loaded).

    Only a regular file of at most :data:`MAX_CALIBRATION_BYTES` is read, without
    blocking (a FIFO, a device or a directory is refused unopened:
    :mod:`gyrotherm._safefile`); nesting and numbers are bounded before parsing."""
    p = Path(path)
    raw = read_bounded(p, max_bytes=MAX_CALIBRATION_BYTES, what="calibration file",
                       error=CalibrationError)
    if raw is None:
        raise CalibrationError(f"{p}: cannot read calibration file: no such file")
    return parse_calibration(raw, source=str(p)), hashlib.sha256(raw).hexdigest()[:16]


def parse_calibration(raw: bytes | str, *, source: str = "<memory>") -> Calibration:
    """Validate calibration JSON text; CalibrationError names ``source`` and the field.
    The text is parsed with :func:`gyrotherm._safefile.parse_json`'s limits (depth,
    integer digits, finite numbers), and the calibration is checked for physical
    plausibility (:func:`~gyrotherm.compensation._plausibility.check_plausible`)."""
    text = (decode_utf8(raw, source=source, error=CalibrationError) if isinstance(raw, bytes)
            else raw)
    data = parse_json(text, source=source, error=CalibrationError)
    return parse_data(data, source)


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


def _check_keys(data: dict[str, Any], version: int, source: str) -> None:
    """CalibrationError naming ``source``, the object, the unknown key(s) and the known
    ones when a closed object holds a key its version does not define (a typo such as
    ``"scalling"`` or ``"t_min"`` would otherwise be ignored silently)."""
    for path, keys in known_keys(version).items():
        node: Any = data
        for part in path.split(".") if path else ():
            node = node.get(part) if isinstance(node, dict) else None
        if not isinstance(node, dict):
            continue  # missing or not an object: _get names it
        unknown = set(node) - keys
        if unknown:
            where = f"field {path!r}" if path else "the top level"
            raise CalibrationError(f"{source}: unknown key(s) {sorted(unknown)} in {where}; "
                                   f"known: {sorted(keys)}")


def parse_data(data: Any, source: str) -> Calibration:
    """Validate decoded JSON (:meth:`Calibration.from_dict`)."""
    if not isinstance(data, dict):
        raise CalibrationError(f"{source}: expected a JSON object at top level")
    schema = _get(data, "schema", str, source)
    if schema != SCHEMA:
        raise CalibrationError(f"{source}: field 'schema': expected {SCHEMA!r}, got {schema!r}")
    version = _get(data, "version", int, source)
    if version not in VERSIONS:
        raise CalibrationError(
            f"{source}: field 'version': unsupported calibration version {version} "
            f"(this gyrotherm reads versions {', '.join(map(str, VERSIONS))})"
        )
    _check_keys(data, version, source)
    units = _get(data, "units", dict, source)
    for key, unit in [*UNITS.items(), *([TIME_UNIT] if version == VERSION_EFFECTS else [])]:
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
        if version == VERSION_EFFECTS:
            parse_runtime_state(_get(data, "runtime_state", dict, source), source)
            cal = replace(cal, effects=parse_effects(_get(data, "effects", dict, source),
                                                     cal.axes, source))
        _check_physical(data, cal, source)
        check_plausible(cal)
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
