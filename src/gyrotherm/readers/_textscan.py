"""Scanning and parsing delimited text in bounded memory: the header, field counts,
and the mapped columns as float arrays.

The file is never held in memory as text: one streamed Python pass over its lines
checks the field counts (a few hundred ns per line) and hashes it, and
``numpy.loadtxt`` (C) parses the mapped columns from the file itself. Only when
that fails does a Python pass look for the first offending cell, to name its line
and column.
"""

from __future__ import annotations

import csv
import hashlib
from array import array
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError

FloatArray = NDArray[np.float64]
DELIMITERS = (",", ";", "\t")
NAMES = {",": "comma", ";": "semicolon", "\t": "tab", " ": "whitespace"}


def detect_delimiter(header: str) -> str:
    """The most frequent of ``,`` ``;`` tab in ``header``, else ``" "`` (whitespace)."""
    counts = {d: header.count(d) for d in DELIMITERS}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else " "


def split(line: str, delimiter: str) -> list[str]:
    """The fields of one line (double quotes honoured), stripped."""
    if delimiter == " ":
        return line.split()
    if '"' not in line:
        return [c.strip() for c in line.rstrip("\r\n").split(delimiter)]
    return [c.strip() for c in next(csv.reader([line.rstrip("\r\n")], delimiter=delimiter))]


def _skip(line: str) -> bool:
    s = line.strip()
    return not s or s.startswith("#")


@dataclass(frozen=True)
class Table:
    """A delimited text file's header and the location of its data rows."""

    path: Path
    header: list[str]
    header_line: int
    delimiter: str
    rows: int
    """Number of data rows."""
    skipped: NDArray[np.int64]
    """Line numbers of the blank and comment lines after the header."""
    sha256: str
    """Of the file's bytes."""

    def line_of(self, row: int) -> int:
        """The file line number of data row ``row`` (0-based)."""
        line = self.header_line + 1 + row
        while True:
            moved = self.header_line + 1 + row + int(np.searchsorted(self.skipped, line,
                                                                       side="right"))
            if moved == line:
                return line
            line = moved

    @property
    def delimiter_name(self) -> str:
        return NAMES.get(self.delimiter, repr(self.delimiter))


@dataclass(frozen=True)
class Header:
    """The header line: its number, fields and delimiter."""

    line: int
    fields: list[str]
    delimiter: str

    @property
    def delimiter_name(self) -> str:
        return NAMES.get(self.delimiter, repr(self.delimiter))


def lines(path: Path) -> Iterator[tuple[int, str]]:
    """``(line number, text)`` of every line of UTF-8 file ``path`` (BOM dropped),
    streamed; RunFileError names the file (and line) when it is unreadable."""
    try:
        with path.open("rb") as fh:
            for line_no, raw in enumerate(fh, start=1):
                try:
                    line = raw.decode("utf-8")
                except UnicodeDecodeError as exc:
                    raise RunFileError(f"{path}: line {line_no}: not UTF-8 text (byte "
                                       f"{exc.start + 1} of the line)") from exc
                yield line_no, line.removeprefix("\ufeff") if line_no == 1 else line
    except OSError as exc:
        raise RunFileError(f"{path}: cannot read: {exc.strerror}") from exc


def find_header(path: Path, delimiter: str | None) -> Header:
    """The first line that is neither blank nor a comment, split by ``delimiter``
    (None = :func:`detect_delimiter`)."""
    for line_no, line in lines(path):
        if not _skip(line):
            delim = delimiter or detect_delimiter(line)
            return Header(line_no, split(line, delim), delim)
    raise RunFileError(f"{path}: no header line (the file is empty or all comments)")


def scan(path: Path, head: Header) -> Table:
    """Check every data line's field count; the table of the data after ``head``."""
    header, delim = head.fields, head.delimiter
    width, commas = len(header), len(header) - 1
    skipped = array("q")
    rows = 0
    for line_no, line in lines(path):
        if line_no <= head.line:
            continue
        if _skip(line):
            skipped.append(line_no)
            continue
        rows += 1
        if delim != " " and '"' not in line and line.count(delim) == commas:
            continue
        got = len(split(line, delim))
        if got != width:
            raise RunFileError(f"{path}: line {line_no}: expected {width} fields "
                               f"({head.delimiter_name}-separated), got {got}")
    if not rows:
        raise RunFileError(f"{path}: line {head.line + 1}: no data rows after the header")
    return Table(path, header, head.line, delim, rows, np.frombuffer(skipped, np.int64),
                 _sha256(path))


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _loadtxt(table: Table, columns: list[int], dtype: type) -> NDArray[np.generic] | None:
    try:
        data: NDArray[np.generic] = np.loadtxt(
            table.path, delimiter=None if table.delimiter == " " else table.delimiter,
            usecols=columns, comments="#", dtype=dtype, ndmin=2, skiprows=table.header_line,
            encoding="utf-8-sig", quotechar=None if table.delimiter == " " else '"')
    except ValueError:
        return None
    return data if data.shape == (table.rows, len(columns)) else None


def numbers(table: Table, columns: list[str]) -> dict[str, FloatArray]:
    """The named columns as finite floats; RunFileError names line, column and cell."""
    index = [table.header.index(c) for c in columns]
    data = _loadtxt(table, index, np.float64)
    if data is None:
        data = _python_numbers(table, columns, index)
    values = np.asarray(data, dtype=np.float64)
    bad = ~np.isfinite(values)
    if bad.any():
        row, j = map(int, np.argwhere(bad)[0])
        line = table.line_of(row)
        text = next(t for n, t in lines(table.path) if n == line)
        cell = split(text, table.delimiter)[index[j]]
        raise RunFileError(f"{table.path}: line {line}: column {columns[j]!r}: "
                           f"{cell!r} is not a finite number")
    return {c: values[:, j] for j, c in enumerate(columns)}  # views: Run copies them


def _number(cell: str, delimiter: str) -> float:
    """``float(cell)``; where the delimiter is not a comma, a decimal comma
    (``20,5``, as spreadsheets write in many locales) is accepted too."""
    try:
        return float(cell)
    except ValueError:
        if delimiter == "," or cell.count(",") != 1 or "." in cell:
            raise
        return float(cell.replace(",", "."))


def _python_numbers(table: Table, columns: list[str], index: list[int]) -> FloatArray:
    """What loadtxt refused, cell by cell (decimal commas accepted, see
    :func:`_number`): the first bad cell is an error."""
    out = array("d")
    for line_no, line in lines(table.path):
        if line_no <= table.header_line or _skip(line):
            continue
        fields = split(line, table.delimiter)
        for j, i in enumerate(index):
            try:
                out.append(_number(fields[i], table.delimiter))
            except ValueError as exc:
                cell = fields[i]
                raise RunFileError(
                    f"{table.path}: line {line_no}: column {columns[j]!r}: "
                    f"{cell!r} is {'blank' if not cell else 'not a number'}") from exc
    return np.frombuffer(out, np.float64).reshape(-1, len(index))


def labels(table: Table, columns: list[str]) -> NDArray[np.str_]:
    """The named columns as strings, one row per data row (grouping keys)."""
    index = [table.header.index(c) for c in columns]
    data = _loadtxt(table, index, str)
    if data is None:  # pragma: no cover  (every line has the header's field count)
        raise RunFileError(f"{table.path}: columns {columns}: unreadable")
    return np.asarray(data, dtype=np.str_)
