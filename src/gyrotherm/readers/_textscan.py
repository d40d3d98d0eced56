"""Scanning and parsing delimited text in bounded memory: the header, field counts,
and the mapped columns as float arrays.

The file is never held in memory as text: one streamed Python pass over its lines
checks the field counts (a few hundred ns per line) and hashes it, and
``numpy.loadtxt`` (C) parses the mapped columns from the file itself. Only when
that fails does a Python pass look for the first offending cell, to name its line
and column.

A serial capture (a terminal's log of what a board printed) differs from a logger's
CSV in three ways, each handled here:

* **no header**: at least half of the first line's fields are numbers (and they are not
  the labels ``0…n−1``/``1…n``); its columns are then named by their 1-based number
  (``"1"``, ``"2"``, …), and the field count is the most common one over the first
  :data:`WIDTH_LINES` lines (a capture may start mid-line) (:func:`find_header`);
* **banner lines**: PuTTY writes ``=~=~=~=…= PuTTY log <date> <time> =~=…`` at the top
  of each session it logs (:data:`PUTTY_BANNER`); skipped like comments;
* **damaged lines**: a line cut short, two lines run together, a token garbled by a
  dropped byte. By default the first is an error naming the line; with
  ``bad_lines="skip"`` each such line is dropped and listed with its reason
  (:attr:`Table.dropped`), so nothing is lost without a word.
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
PUTTY_BANNER = "=~=~=~=~=~=~=~=~=~=~=~= PuTTY log "
"""How a PuTTY session log's banner line starts (PuTTY's ``logging.c``)."""
WIDTH_LINES = 200
"""Lines of a headerless file whose most common field count is its width."""
BAD_LINES = ("error", "skip")
"""What a data line with the wrong field count, a mapped cell that is not a finite
number or a blank device/run cell does: stop with an error naming it, or be dropped and
listed."""


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


def _comment(line: str) -> bool:
    """Skipped by ``numpy.loadtxt`` too (blank or ``#``)."""
    s = line.strip()
    return not s or s.startswith("#")


def _skip(line: str) -> bool:
    """Not a data line: blank, a ``#`` comment or a PuTTY banner."""
    return _comment(line) or line.lstrip().startswith(PUTTY_BANNER)


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
    """Line numbers of the lines after the header that are not data rows: blank,
    comment and banner lines, and the ``dropped`` ones."""
    sha256: str
    """Of the file's bytes."""
    dropped: tuple[tuple[int, str], ...] = ()
    """(line number, reason) of each damaged line dropped (``bad_lines="skip"``)."""
    plain: bool = True
    """Every skipped line is blank or a ``#`` comment (``numpy.loadtxt`` can read the
    file itself); else the data lines are handed to it one by one."""

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
    """The header line: its number, fields and delimiter. A headerless file
    (``named`` False): ``line`` is the line before the first data line and ``fields``
    are the column numbers ``"1"`` … ``"<width>"``."""

    line: int
    fields: list[str]
    delimiter: str
    named: bool = True
    first: tuple[str, ...] = ()
    """A headerless file's first line of its width, split (for messages)."""

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


def _numeric_share(fields: list[str]) -> float:
    """The share of the non-empty fields that are numbers (0 for none)."""
    cells = [f for f in fields if f]
    if not cells:
        return 0.0
    count = 0
    for f in cells:
        try:
            float(f)
        except ValueError:
            continue
        count += 1
    return count / len(cells)


def _integer_labels(fields: list[str]) -> bool:
    """``0 1 … n−1`` or ``1 2 … n``: the column labels a dataframe writes when its
    columns have no names (``pandas.DataFrame.to_csv`` of a numpy array)."""
    return fields in ([str(i) for i in range(len(fields))],
                      [str(i) for i in range(1, len(fields) + 1)])


def find_header(path: Path, delimiter: str | None) -> Header:
    """The first line that is neither blank nor a comment nor a banner, split by
    ``delimiter`` (None = :func:`detect_delimiter`). It is the header unless at least
    half of its fields are numbers and they are not the labels ``0…n−1``/``1…n``
    (a damaged first data line is still data); then the file has none
    (:class:`Header`, module docstring): its delimiter is detected over the first
    :data:`WIDTH_LINES` lines when the first has none (a capture may start with a
    one-field fragment), and its width is their most common field count."""
    sample: list[tuple[int, str]] = []
    for line_no, line in lines(path):
        if _skip(line):
            continue
        if not sample:
            delim = delimiter or detect_delimiter(line)
            fields = split(line, delim)
            if _numeric_share(fields) < 0.5 or _integer_labels(fields):
                return Header(line_no, fields, delim)
        sample.append((line_no, line))
        if len(sample) >= WIDTH_LINES:
            break
    if not sample:
        raise RunFileError(f"{path}: no header line (the file is empty or all comments)")
    delim = delimiter or detect_delimiter(sample[0][1])
    if delimiter is None and delim == " " and not sample[0][1].strip().count(" "):
        delim = detect_delimiter("".join(text for _, text in sample))
    split_lines = [split(text, delim) for _, text in sample]
    counts: dict[int, int] = {}
    for fields in split_lines:
        counts[len(fields)] = counts.get(len(fields), 0) + 1
    width = max(counts, key=lambda n: (counts[n], n))
    shown = next(f for f in split_lines if len(f) == width)
    return Header(sample[0][0] - 1, [str(i) for i in range(1, width + 1)], delim, named=False,
                  first=tuple(shown))


def scan(path: Path, head: Header, *, bad_lines: str = "error",
         numeric: tuple[int, ...] = (), labelled: tuple[int, ...] = ()) -> Table:
    """Check every data line's field count; the table of the data after ``head``.
    ``bad_lines="skip"``: a line with the wrong field count, whose columns ``numeric``
    (0-based) are not all finite numbers, or whose grouping columns ``labelled`` are
    blank, is dropped with its reason."""
    if bad_lines not in BAD_LINES:
        raise ValueError(f"bad_lines = {bad_lines!r}; known: {', '.join(BAD_LINES)}")
    header, delim = head.fields, head.delimiter
    width, commas = len(header), len(header) - 1
    skip = bad_lines == "skip"
    skipped = array("q")
    dropped: list[tuple[int, str]] = []
    plain = True
    rows = 0
    for line_no, line in lines(path):
        if line_no <= head.line:
            continue
        if _skip(line):
            skipped.append(line_no)
            plain = plain and _comment(line)
            continue
        if not skip and delim != " " and '"' not in line and line.count(delim) == commas:
            rows += 1
            continue
        fields = split(line, delim)
        why = (f"expected {width} fields ({head.delimiter_name}-separated), got {len(fields)}"
               if len(fields) != width else (_bad_cell(fields, numeric, labelled, header,
                                                       delim) if skip else None))
        if why is None:
            rows += 1
        elif skip:
            skipped.append(line_no)
            dropped.append((line_no, why))
            plain = False
        else:
            raise RunFileError(f"{path}: line {line_no}: {why} (a serial capture with damaged "
                               "lines? --bad-lines skip drops them and lists them in the run's "
                               "metadata)")
    if not rows:
        raise RunFileError(f"{path}: line {head.line + 1}: no data rows after the header")
    return Table(path, header, head.line, delim, rows, np.frombuffer(skipped, np.int64),
                 _sha256(path), tuple(dropped), plain)


def _bad_cell(fields: list[str], numeric: tuple[int, ...], labelled: tuple[int, ...],
              header: list[str], delimiter: str) -> str | None:
    """Why one of the ``numeric`` cells of a line is not a finite number, or one of the
    ``labelled`` ones is blank, else None."""
    for i in labelled:
        if not fields[i]:
            return f"column {header[i]!r} is blank"
    for i in numeric:
        try:
            value = _number(fields[i], delimiter)
        except ValueError:
            return f"column {header[i]!r}: {fields[i]!r} is not a number"
        if not np.isfinite(value):
            return f"column {header[i]!r}: {fields[i]!r} is not a finite number"
    return None


def data_lines(table: Table) -> Iterator[tuple[int, str]]:
    """``(line number, text)`` of the table's data rows, in order."""
    skipped = iter(table.skipped.tolist())
    nxt = next(skipped, None)
    for line_no, line in lines(table.path):
        if line_no <= table.header_line:
            continue
        while nxt is not None and nxt < line_no:
            nxt = next(skipped, None)
        if nxt == line_no or _skip(line):
            continue
        yield line_no, line


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _loadtxt(table: Table, columns: list[int], dtype: type) -> NDArray[np.generic] | None:
    source: Path | Iterator[str] = table.path
    if not table.plain:  # banner or dropped lines: hand loadtxt the data rows alone
        source = (line for _, line in data_lines(table))
    try:
        data: NDArray[np.generic] = np.loadtxt(
            source, delimiter=None if table.delimiter == " " else table.delimiter,
            usecols=columns, comments="#", dtype=dtype, ndmin=2,
            skiprows=table.header_line if table.plain else 0,
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
    for line_no, line in data_lines(table):
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
