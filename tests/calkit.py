"""Test helper for calibration files: a copy of a document with one field changed."""

from __future__ import annotations

import json
from typing import Any

DELETE = object()
"""As ``value`` of :func:`broken`: remove the field instead."""


def broken(doc: dict[str, Any], path: str, value: object) -> dict[str, Any]:
    """A deep copy of ``doc`` with the dotted ``path`` set to ``value`` (or deleted)."""
    out = json.loads(json.dumps(doc))
    node = out
    keys = path.split(".")
    for k in keys[:-1]:
        node = node[k]
    if value is DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return out
