"""``--json`` output is always valid JSON: no bare ``NaN``/``Infinity``.

Python's :mod:`json` writes non-finite floats as ``NaN``, ``Infinity``, which no
JSON parser has to accept. :func:`dumps` writes ``null`` in their place and lists
each such field, by its path, under the top-level key ``null_reasons`` with why
(``"NaN: not computable (no rows)"``, ``"Infinity: ..."``).
"""

from __future__ import annotations

import json
import math
from typing import Any

NULL_REASONS_KEY = "null_reasons"
_REASON = {"nan": "NaN: not computable (no rows, or an undefined ratio)",
           "inf": "Infinity: unbounded (e.g. a singular design matrix)",
           "-inf": "-Infinity: unbounded"}


def _clean(value: Any, path: str, notes: dict[str, str]) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        notes[path] = _REASON[str(value)]
        return None
    if isinstance(value, dict):
        return {k: _clean(v, f"{path}.{k}" if path else str(k), notes) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v, f"{path}[{i}]", notes) for i, v in enumerate(value)]
    return value


def json_safe(data: Any) -> Any:
    """``data`` with every non-finite float replaced by None, and (for a dict) the
    replaced paths under ``null_reasons``."""
    notes: dict[str, str] = {}
    clean = _clean(data, "", notes)
    if notes and isinstance(clean, dict):
        clean[NULL_REASONS_KEY] = notes
    return clean


def dumps(data: Any) -> str:
    """Strict JSON of :func:`json_safe` (``allow_nan=False``), indented by 2."""
    return json.dumps(json_safe(data), indent=2, allow_nan=False)


__all__ = ["NULL_REASONS_KEY", "dumps", "json_safe"]
