"""Delimited text (CSV, TSV, ``;``, whitespace) with a column map → runs.

* UTF-8, with or without a byte-order mark; lines starting with ``#`` and blank
  lines are skipped anywhere; the first other line is the header (required).
* Delimiter: given, or detected from the header: the most frequent of ``,``
  ``;`` and tab, else runs of whitespace. Fields may be double-quoted.
* Columns: ``--columns`` (:func:`gyrotherm.readers.parse_columns`) or a
  recognised header (:mod:`gyrotherm.readers._headers`). Mapped cells must be
  finite numbers; other columns are ignored.
* ``device`` / ``run`` roles split the rows into one run per value (in order of
  first appearance); time must increase strictly within each run.

Errors are :class:`gyrotherm.RunFileError` naming file, line, column and problem,
and for a header that does not fit, the columns found and the roles needed.
"""

from __future__ import annotations

import csv
import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._headers import example_columns, recognise
from gyrotherm.readers._spec import ACCEL_EXTRA, GROUP_ROLES, RATE_ROLES, ColumnMap

FloatArray = NDArray[np.float64]
_DELIMITERS = (",", ";", "\t")
_NAMES = {",": "comma", ";": "semicolon", "\t": "tab", " ": "whitespace"}


@dataclass(frozen=True)
class _Table:
    header: list[str]
    header_line: int
    line_no: NDArray[np.int64]
    cells: dict[str, list[str]]
    delimiter: str


def detect_delimiter(header: str) -> str:
    """The most frequent of ``,`` ``;`` tab in ``header``, else ``" "`` (whitespace)."""
    counts = {d: header.count(d) for d in _DELIMITERS}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else " "


def _split(line: str, delimiter: str) -> list[str]:
    if delimiter == " ":
        return line.split()
    return [c.strip() for c in next(csv.reader([line], delimiter=delimiter))]


def _decode(path: Path) -> tuple[str, str]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise RunFileError(f"{path}: cannot read: {exc.strerror}") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RunFileError(f"{path}: not UTF-8 text (byte {exc.start})") from exc
    return text, hashlib.sha256(raw).hexdigest()


def _table(path: Path, text: str, delimiter: str | None, wanted: ColumnMap | None,
           ) -> tuple[_Table, ColumnMap, str]:
    rows = [(i, s) for i, s in enumerate(text.splitlines(), start=1)
            if s.strip() and not s.lstrip().startswith("#")]
    if not rows:
        raise RunFileError(f"{path}: no header line (the file is empty or all comments)")
    header_line, head = rows[0]
    delim = delimiter or detect_delimiter(head)
    header = _split(head, delim)
    if wanted is None:
        known = recognise(header, path.stem)
        if known is None:
            raise RunFileError(
                f"{path}: line {header_line}: cannot tell which columns hold time, "
                f"temperature and rate, nor their units (columns found: {header}; roles "
                f"needed: time, temperature, at least one of x, y, z); give them, e.g. "
                f"{example_columns(header)}")
        wanted, schema = known
    else:
        schema = "columns given"
    absent = [r.token() for r in wanted.roles if r.column not in header]
    if absent:
        raise RunFileError(
            f"{path}: line {header_line}: --columns {' '.join(absent)}: no such column "
            f"(columns found with {_NAMES.get(delim, repr(delim))} delimiter: {header}; "
            f"columns needed: {[r.column for r in wanted.roles]})")
    index = {r.column: header.index(r.column) for r in wanted.roles}
    cells: dict[str, list[str]] = {c: [] for c in index}
    numbers = []
    for line_no, line in rows[1:]:
        fields = _split(line, delim)
        if len(fields) != len(header):
            raise RunFileError(f"{path}: line {line_no}: expected {len(header)} fields "
                               f"({_NAMES.get(delim, repr(delim))}-separated), got "
                               f"{len(fields)}")
        for c, j in index.items():
            cells[c].append(fields[j])
        numbers.append(line_no)
    if not numbers:
        raise RunFileError(f"{path}: line {header_line + 1}: no data rows after the header")
    return (_Table(header, header_line, np.array(numbers, dtype=np.int64), cells, delim),
            wanted, schema)


def _numbers(path: Path, table: _Table, column: str) -> FloatArray:
    strings = table.cells[column]
    try:
        values = np.array(strings, dtype=np.float64)
    except ValueError:
        values = None
    if values is None:
        for k, s in enumerate(strings):
            try:
                float(s)
            except ValueError:
                raise RunFileError(
                    f"{path}: line {table.line_no[k]}: column {column!r}: "
                    f"{s!r} is {'blank' if not s else 'not a number'}") from None
        raise RunFileError(f"{path}: column {column!r}: unreadable")  # pragma: no cover
    bad = ~np.isfinite(values)
    if bad.any():
        k = int(np.argmax(bad))
        raise RunFileError(f"{path}: line {table.line_no[k]}: column {column!r}: "
                           f"{strings[k]!r} is not a finite number")
    return values


def read_text(path: str | Path, *, columns: ColumnMap | None = None,
              delimiter: str | None = None) -> list[Run]:
    """The runs in delimited text file ``path`` (see the module docstring)."""
    p = Path(path)
    text, sha = _decode(p)
    table, cmap, schema = _table(p, text, delimiter, columns)
    values: dict[str, FloatArray] = {}
    for r in cmap.roles:
        if r.unit is not None:
            values[r.role] = _numbers(p, table, r.column) * r.unit.scale + r.unit.offset
    groups = [g for g in GROUP_ROLES if cmap.get(g) is not None]
    keys = [tuple(table.cells[cmap.column_of(g)][k] for g in groups)
            for k in range(len(table.line_no))] if groups else [()] * len(table.line_no)
    order = list(dict.fromkeys(keys))
    base = {"format": "text", "schema": schema, "columns": cmap.tokens(),
            "delimiter": _NAMES.get(table.delimiter, table.delimiter),
            **{f"unit_{r.role}": r.unit.name for r in cmap.roles if r.unit is not None}}
    runs = []
    key_array = np.array(["\x1f".join(k) for k in keys])
    for instance, key in enumerate(order):
        rows = np.flatnonzero(key_array == "\x1f".join(key)) if groups else \
            np.arange(len(keys))
        meta = dict(base)
        label = dict(zip(groups, key, strict=True))
        meta["device_id"] = label.get("device", "")
        meta["instance"] = str(instance)
        if "run" in label:
            meta["segment"] = label["run"]
        t = values["time"][rows]
        steps = np.diff(t)
        if (steps <= 0).any():
            k = int(np.argmax(steps <= 0)) + 1
            where = f" (run {':'.join(key)})" if groups else ""
            raise RunFileError(
                f"{p}: line {table.line_no[rows[k]]}: column {cmap.column_of('time')!r}"
                f"{where}: time not increasing ({t[k - 1]:.9g} s then {t[k]:.9g} s)")
        name = p.stem if len(order) == 1 else f"{p.stem}:{':'.join(key)}"
        runs.append(Run(
            name=name, time_s=t, temperature_c=values["temperature"][rows],
            rates_dps={a: values[a][rows] for a in RATE_ROLES if a in values},
            metadata=meta, source=str(p), sha256=sha,
            extra={ACCEL_EXTRA[r]: values[r][rows] for r in ACCEL_EXTRA if r in values}))
    return runs
