"""Delimited text (CSV, TSV, ``;``, whitespace) with a column map → runs.

* UTF-8, with or without a byte-order mark; lines starting with ``#``, blank
  lines and PuTTY's session-log banners are skipped anywhere; the first other line
  is the header, unless at least half of it is numbers: then the file has none and
  its columns are named by number from 1 (a serial capture,
  :func:`~._textscan.find_header`).
* Delimiter: given, or detected from the header: the most frequent of ``,``
  ``;`` and tab, else runs of whitespace. Fields may be double-quoted.
* Columns: ``--columns`` (:func:`gyrotherm.readers.parse_columns`) or a
  recognised header (:mod:`gyrotherm.readers._headers`). Mapped cells must be
  finite numbers; other columns are ignored.
* ``device`` / ``run`` roles split the rows into one run per value (in order of
  first appearance); time must increase strictly within each run. Without a time
  column, the map's nominal rate gives time = row index / rate within each run
  (metadata ``time_source``).
* ``bad_lines="skip"``: a damaged line (wrong field count, a mapped cell that is not a
  finite number, a blank device/run cell) is dropped; each run's metadata
  ``dropped_lines`` lists the file's (count, then line: reason).

Errors are :class:`gyrotherm.RunFileError` naming file, line, column and problem,
and for a header that does not fit, the columns found and the roles needed.
Parsing: :mod:`gyrotherm.readers._textscan`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._headers import example_columns, recognise
from gyrotherm.readers._spec import ACCEL_EXTRA, GROUP_ROLES, RATE_ROLES, ColumnMap
from gyrotherm.readers._textscan import Header, Table, find_header, labels, numbers, scan

FloatArray = NDArray[np.float64]


DROPPED_LISTED = 20
"""Dropped lines listed by number and reason in the metadata (the count is always)."""


def _column_map(path: Path, head: Header, wanted: ColumnMap | None,
                ) -> tuple[ColumnMap, str]:
    header = head.fields
    if wanted is None and not head.named:
        shown = ", ".join(f"{i}: {v}" for i, v in enumerate(head.first, start=1))
        raise RunFileError(
            f"{path}: line {head.line + 1}: the file has no header (its lines are numbers, "
            f"e.g. {shown}): give the columns by number, from 1, with their units, and the time "
            "as a column or, for a log without time stamps, its sample rate, e.g. --columns "
            "temperature=<N>:degC x=<N>:dps y=<N>:dps z=<N>:dps --rate-hz <HZ>")
    if wanted is None:
        known = recognise(header, path.stem)
        if known is None:
            raise RunFileError(
                f"{path}: line {head.line}: cannot tell which columns hold time, "
                f"temperature and rate, nor their units (columns found: {header}; roles "
                f"needed: time, temperature, at least one of x, y, z); give them, e.g. "
                f"{example_columns(header)}")
        wanted, schema = known
    else:
        schema = "columns given"
    absent = [r.token() for r in wanted.roles if r.column not in header]
    if absent and not head.named:
        raise RunFileError(
            f"{path}: line {head.line + 1}: --columns {' '.join(absent)}: no such column (the "
            f"file has no header: its columns are numbered 1 to {len(header)}, "
            f"{head.delimiter_name}-separated)")
    if absent:
        raise RunFileError(
            f"{path}: line {head.line}: --columns {' '.join(absent)}: no such column "
            f"(columns found with {head.delimiter_name} delimiter: {header}; "
            f"columns needed: {[r.column for r in wanted.roles]})")
    return wanted, schema


def _groups(table: Table, cmap: ColumnMap) -> tuple[list[str], list[tuple[str, ...]],
                                                   list[NDArray[np.intp] | slice]]:
    """Grouping roles, the key of each group (first appearance order) and its rows."""
    roles = [g for g in GROUP_ROLES if cmap.get(g) is not None]
    if not roles:
        return roles, [()], [slice(None)]
    keys = labels(table, [cmap.column_of(g) for g in roles])
    joined = keys[:, 0] if len(roles) == 1 else np.char.add(np.char.add(keys[:, 0], "\x1f"),
                                                            keys[:, 1])
    _, first, inverse = np.unique(joined, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rows: list[NDArray[np.intp] | slice] = [np.flatnonzero(inverse == g) for g in order]
    firsts = first[order]
    return roles, [tuple(str(v) for v in keys[i]) for i in firsts], rows


def _dropped(table: Table) -> str:
    shown = "; ".join(f"line {n}: {why}" for n, why in table.dropped[:DROPPED_LISTED])
    more = len(table.dropped) - DROPPED_LISTED
    return f"{len(table.dropped)}: {shown}" + (f"; and {more} more" if more > 0 else "")


def read_text(path: str | Path, *, columns: ColumnMap | None = None,
              delimiter: str | None = None, bad_lines: str = "error") -> list[Run]:
    """The runs in delimited text file ``path`` (see the module docstring)."""
    p = Path(path)
    head = find_header(p, delimiter)
    cmap, schema = _column_map(p, head, columns)
    measured = [r for r in cmap.roles if r.unit is not None]
    table = scan(p, head, bad_lines=bad_lines,
                 numeric=tuple(head.fields.index(r.column) for r in measured),
                 labelled=tuple(head.fields.index(cmap.column_of(g)) for g in GROUP_ROLES
                                if cmap.get(g) is not None))
    raw = numbers(table, [r.column for r in measured])
    values: dict[str, FloatArray] = {}
    for r in measured:
        assert r.unit is not None
        shared = sum(m.column == r.column for m in measured) > 1
        v = raw[r.column].copy() if shared else raw[r.column]
        if (r.unit.scale, r.unit.offset) != (1.0, 0.0):
            v *= r.unit.scale  # in place: the loaded block is this reader's own
            v += r.unit.offset
        values[r.role] = v
    del raw
    roles, keys, groups = _groups(table, cmap)
    base = {"format": "text", "schema": schema, "columns": cmap.tokens(),
            "delimiter": table.delimiter_name,
            **{f"unit_{r.role}": r.unit.name for r in measured if r.unit is not None}}
    if not head.named:
        base["header"] = "none (columns numbered from 1)"
    if cmap.rate_hz is not None:
        base["time_source"] = (f"nominal: row index / {cmap.rate_hz:g} Hz (the log has no "
                               "time stamps; dropped lines are not counted)")
    if table.dropped:
        base["dropped_lines"] = _dropped(table)
    runs = []
    for instance, (key, rows) in enumerate(zip(keys, groups, strict=True)):
        label = dict(zip(roles, key, strict=True))
        meta = {**base, "device_id": label.get("device", ""), "instance": str(instance)}
        if "run" in label:
            meta["segment"] = label["run"]
        if cmap.rate_hz is None:
            t = values["time"][rows]
        else:
            n = table.rows if isinstance(rows, slice) else len(rows)
            t = np.arange(n, dtype=np.float64) / cmap.rate_hz
        steps = np.diff(t)
        if (steps <= 0).any():
            k = int(np.argmax(steps <= 0)) + 1
            where = f" (run {':'.join(key)})" if roles else ""
            row = k if isinstance(rows, slice) else int(rows[k])
            raise RunFileError(
                f"{p}: line {table.line_of(row)}: column "
                f"{cmap.column_of('time')!r}{where}: time not increasing "
                f"({t[k - 1]:.9g} s then {t[k]:.9g} s)")
        runs.append(Run(
            name=p.stem if len(keys) == 1 else f"{p.stem}:{':'.join(key)}",
            time_s=t, temperature_c=values["temperature"][rows],
            rates_dps={a: values[a][rows] for a in RATE_ROLES if a in values},
            metadata=meta, source=str(p), sha256=table.sha256,
            extra={ACCEL_EXTRA[r]: values[r][rows] for r in ACCEL_EXTRA if r in values}))
    return runs
