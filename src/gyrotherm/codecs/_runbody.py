"""The data rows of a run file: numpy's C parser, a chunk of text at a time.

A clean file (the common case) is parsed in one pass of ≈ 1 MiB chunks straight
into one read-only array per column, so a 3.6·10⁶-row log costs its text plus
its columns, not millions of line objects or a 4-byte-per-character copy.
A file with an error in it takes the slow path, which names the line and column.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import NoReturn

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError

FloatArray = NDArray[np.float64]

_CHUNK_CHARS = 1 << 20


def _chunks(text: str, start: int = 0, end: int | None = None) -> Iterator[list[str]]:
    """The lines of ``text[start:end]``, a list of about 1 MiB of text at a time
    (chunks end at a line end; a line longer than a chunk is one chunk)."""
    stop = len(text) if end is None else end
    pos = start
    while pos < stop:
        if stop - pos <= _CHUNK_CHARS:
            cut = stop
        else:  # end the chunk after its last complete line (or the first, if longer)
            cut = text.rfind("\n", pos, pos + _CHUNK_CHARS)
            if cut < 0:
                cut = text.find("\n", pos + _CHUNK_CHARS, stop)
                cut = stop if cut < 0 else cut
        yield text[pos:cut].splitlines()
        pos = cut + 1


def _load_columns(
    text: str, start: int, end: int, n_rows: int, width: int
) -> list[FloatArray] | None:
    """The body's columns (each its own array of ``n_rows``), filled a chunk at a
    time, or None when a chunk does not parse or the rows do not add up to
    ``n_rows`` (blank lines).

    np.loadtxt on one ``io.StringIO(text)`` would first copy the whole text into a
    4-byte-per-character buffer (0.6 GB for a 1-hour 1 kHz log); here the peak is
    the text, the columns and one chunk.
    """
    out = [np.empty(n_rows) for _ in range(width)]
    row = 0
    for lines in _chunks(text, start, end):
        try:
            block = _loadtxt_lines(lines, width)
        except ValueError:
            return None
        if block.shape[1] != width or row + len(block) > n_rows:
            return None
        for j in range(width):
            out[j][row:row + len(block)] = block[:, j]
        row += len(block)
    return out if row == n_rows else None


def _loadtxt_lines(lines: list[str], width: int) -> FloatArray:
    if not any(lines):  # nothing but blank lines (np.loadtxt would warn)
        return np.empty((0, width))
    data: FloatArray = np.loadtxt(
        lines, delimiter=",", ndmin=2, dtype=np.float64, comments=None)
    return data


def _loadtxt(text: str, usecols: list[int] | None = None) -> FloatArray:
    data: FloatArray = np.loadtxt(
        io.StringIO(text),
        delimiter=",",
        ndmin=2,
        dtype=np.float64,
        comments=None,
        usecols=usecols,
    )
    return data


def _body_rows(text: str, start: int) -> tuple[int, int]:
    """End of the body without trailing blank lines, and its number of lines."""
    end = len(text)
    while end > start and text[end - 1] in " \t\r\n\f\v":
        end -= 1
    if end <= start:
        return end, 0
    newlines = (text.count("\n", start, end) + text.count("\r", start, end)
                - text.count("\r\n", start, end))
    return end, newlines + 1


def parse_body(
    text: str, start: int, header: list[str], strict_columns: frozenset[str], *,
    source: str, first_line: int,
) -> dict[str, FloatArray]:
    """Columns by header name from the data rows in ``text[start:]``: every known
    column (those in ``strict_columns``), and the unknown ones that are all finite.

    Known columns are strict: a field that is blank, not a number or not finite is
    an error naming line and column. An unknown column that does not parse as
    finite numbers throughout is left out (not an error). Trailing blank lines are
    ignored; blank lines inside the data are errors.
    """
    end, n_rows = _body_rows(text, start)
    if n_rows == 0:
        raise RunFileError(f"{source}: line {first_line}: no data rows")
    width = len(header)
    known = [j for j, h in enumerate(header) if h in strict_columns]
    unknown = [j for j, h in enumerate(header) if h not in strict_columns]
    # Fast path: numpy's C parser a chunk at a time, into one row per column.
    data = _load_columns(text, start, end, n_rows, width)
    if data is not None:
        _check_columns_finite([data[j] for j in known], [header[j] for j in known],
                              source, first_line)
        out: dict[str, FloatArray] = {}
        for j in range(width):
            if j in known or bool(np.isfinite(data[j]).all()):
                column = data[j]
                column.setflags(write=False)
                out[header[j]] = column
        return out
    del data
    # Slow path (a file with an error in it): field counts per line, then the known
    # columns strictly, then each unknown column on its own.
    body = text[start:end].splitlines()
    body_text = "\n".join(body)
    _check_widths(body, width, source, first_line)
    try:
        strict = _loadtxt(body_text, usecols=known)
    except ValueError:
        _explain(body, header, known, source, first_line)
    if strict.shape[0] != len(body):  # pragma: no cover  (blank lines fail the width check)
        raise RunFileError(f"{source}: unreadable data rows")
    _check_finite(strict, [header[j] for j in known], source, first_line)
    col = {header[j]: strict[:, k] for k, j in enumerate(known)}
    for j in unknown:
        try:
            values = _loadtxt(body_text, usecols=[j])[:, 0]
        except ValueError:
            continue
        if len(values) == len(body) and bool(np.isfinite(values).all()):
            col[header[j]] = values
    return col


def _check_columns_finite(
    columns: list[FloatArray], names: list[str], source: str, first_line: int
) -> None:
    """:func:`_check_finite` on separate columns (the first bad field in reading order)."""
    first: tuple[int, int] | None = None
    for k, c in enumerate(columns):
        bad = ~np.isfinite(c)
        if bad.any():
            row = int(np.argmax(bad))
            if first is None or row < first[0]:
                first = (row, k)
    if first is not None:
        raise RunFileError(f"{source}: line {first_line + first[0]}: column "
                           f"{names[first[1]]!r} is not a finite number")


def _check_finite(data: FloatArray, names: list[str], source: str, first_line: int) -> None:
    bad = ~np.isfinite(data)
    if bad.any():
        row, k = map(int, np.argwhere(bad)[0])
        raise RunFileError(
            f"{source}: line {first_line + row}: column {names[k]!r} is not a finite number"
        )


def _check_widths(body: list[str], width: int, source: str, first_line: int) -> None:
    commas = width - 1
    for k, line in enumerate(body):
        if not line.strip():
            raise RunFileError(f"{source}: line {first_line + k}: blank line inside the data")
        if line.count(",") != commas:
            raise RunFileError(
                f"{source}: line {first_line + k}: expected {width} fields, "
                f"got {line.count(',') + 1}"
            )


def _is_number(text: str) -> bool:
    """What np.loadtxt accepts: float() syntax without underscores or non-ASCII digits."""
    if "_" in text or not text.isascii():
        return False
    try:
        float(text)
    except ValueError:
        return False
    return True


def _explain(
    body: list[str], header: list[str], known: list[int], source: str, first_line: int
) -> NoReturn:
    """Raise a RunFileError for the first known field that is blank or not a number."""
    for k, line in enumerate(body):
        fields = line.split(",")
        for j in known:
            field_text = fields[j].strip()
            where = f"{source}: line {first_line + k}: column {header[j]!r}"
            if not field_text:
                raise RunFileError(f"{where} is blank")
            if not _is_number(field_text):
                raise RunFileError(f"{where}: {field_text!r} is not a number")
    raise RunFileError(f"{source}: unreadable data rows")  # pragma: no cover
