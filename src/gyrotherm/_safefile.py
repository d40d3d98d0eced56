"""Bounded, non-blocking reads of the small JSON files the daemon trusts on disk.

The daemon reads two kinds of file it did not write in this run: the calibration
(at start and on SIGHUP) and its own saved state (``state_dir``). Either may have
been replaced by anything an unlucky or hostile operator can put at a path: a FIFO
(``open()`` blocks until a writer appears), a device (``/dev/zero`` never ends), a
directory, a huge file, JSON nested 100 000 deep (``RecursionError``), a
400-digit integer (``OverflowError`` on ``float()``), ``1e999`` (inf) or ``NaN``.

:func:`read_json_file` refuses all of them *before* they can hurt, with one
:class:`~gyrotherm.GyrothermError` subclass (the caller's) naming the file and
the problem:

1. ``os.stat`` (following links: a calibration symlinked for a roll-out is
   fine) must show a **regular file** of at most ``max_bytes``: FIFOs, sockets,
   devices and directories are refused without being opened;
2. it is opened with ``O_NONBLOCK`` (so that a FIFO swapped in between the stat
   and the open cannot block) and ``fstat`` checked again, then at most
   ``max_bytes + 1`` bytes are read (a file that grows is refused, not followed);
3. the text must be UTF-8, nest at most ``max_depth`` arrays/objects (counted
   on the text, outside strings, before ``json`` recurses), and every number must
   be finite: integer literals of at most :data:`MAX_INT_DIGITS` digits, floats
   that do not overflow to ±inf, no ``NaN``/``Infinity`` constants.

So every number handed to the caller is an ``int`` with |v| < 10¹⁹ or a finite
``float``: ``float(v)`` can neither overflow nor give inf/NaN.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any

from gyrotherm._errors import GyrothermError

#: Largest integer literal accepted, in digits (int64 needs 19).
MAX_INT_DIGITS = 19
#: Default deepest nesting of arrays and objects.
MAX_DEPTH = 32
_SPECIAL = re.compile(r'["\\\[\]{}]')


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return name
    return "not a regular file"


def read_bounded(path: Path, *, max_bytes: int, what: str,
                 error: type[GyrothermError]) -> bytes | None:
    """The bytes of the regular file ``path`` (at most ``max_bytes``); None when it does
    not exist; ``error`` naming ``path`` and ``what`` for anything else."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from exc
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: the {what} is {_kind(st.st_mode)}, not a regular file: "
                    "refused without reading it")
    if st.st_size > max_bytes:
        raise error(f"{path}: the {what} is {st.st_size} bytes, more than the "
                    f"{max_bytes} accepted: refused without reading it")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise error(f"{path}: cannot open the {what}: {exc.strerror or exc}") from exc
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped between stat and open
            raise error(f"{path}: the {what} is {_kind(st.st_mode)}, not a regular file")
        chunks, size = [], 0
        while size <= max_bytes:
            chunk = os.read(fd, min(65536, max_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from exc
    finally:
        os.close(fd)
    if size > max_bytes:
        raise error(f"{path}: the {what} grew past {max_bytes} bytes while being read")
    return b"".join(chunks)


def nesting_depth(text: str) -> int:
    """Deepest nesting of ``[``/``{`` in JSON ``text``, brackets inside strings ignored:
    one pass over the characters that matter (quotes, backslashes, brackets), linear in
    the text whatever it holds (a regular expression for strings backtracks
    quadratically on ``"\\"\\"…``)."""
    depth = deepest = 0
    in_string = False
    escaped_at = -1  # the position a backslash escapes
    for m in _SPECIAL.finditer(text):
        i, c = m.start(), m.group()
        if i == escaped_at:
            continue
        if in_string:
            if c == "\\":
                escaped_at = i + 1
            elif c == '"':
                in_string = False
        elif c == '"':
            in_string = True
        elif c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth -= 1
    return deepest


class _Bad:
    """A number literal refused by the parse hooks, kept to name its field afterwards."""

    __slots__ = ("why",)

    def __init__(self, why: str) -> None:
        self.why = why


def _parse_int(s: str) -> int | _Bad:
    digits = len(s.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        return _Bad(f"an integer of {digits} digits (at most {MAX_INT_DIGITS} accepted)")
    return int(s)


def _parse_float(s: str) -> float | _Bad:
    v = float(s)
    return v if math.isfinite(v) else _Bad(f"the number {s[:40]} overflows a double")


def _no_constant(s: str) -> _Bad:
    return _Bad(f"{s} is not a finite number")


def _find_bad(node: Any, path: str) -> tuple[str, str] | None:
    """(field path, reason) of the first refused literal, depth-first (bounded depth)."""
    if isinstance(node, _Bad):
        return path or "the top level", node.why
    items = (node.items() if isinstance(node, dict)
             else enumerate(node) if isinstance(node, list) else ())
    for key, value in items:
        sub = f"{path}[{key}]" if isinstance(key, int) else (f"{path}.{key}" if path else key)
        found = _find_bad(value, sub)
        if found is not None:
            return found
    return None


def parse_json(text: str, *, source: str, error: type[GyrothermError],
               max_depth: int = MAX_DEPTH) -> Any:
    """``text`` as JSON with the limits of the module docstring; ``error`` naming
    ``source`` (and the field, for a refused number) when it breaks one."""
    depth = nesting_depth(text)
    if depth > max_depth:
        raise error(f"{source}: JSON nested {depth} deep (at most {max_depth} accepted)")
    try:
        data = json.loads(text, parse_int=_parse_int, parse_float=_parse_float,
                          parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise error(f"{source}: line {exc.lineno}: not valid JSON ({exc.msg})") from exc
    except (ValueError, RecursionError) as exc:
        raise error(f"{source}: unreadable JSON: {exc}") from exc
    bad = _find_bad(data, "")
    if bad is not None:
        raise error(f"{source}: field {bad[0]!r}: {bad[1]}")
    return data


def decode_utf8(raw: bytes, *, source: str, error: type[GyrothermError]) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{source}: not UTF-8 text (byte {exc.start})") from exc


def read_json_file(path: Path, *, what: str, error: type[GyrothermError],
                   max_bytes: int = 1 << 20, max_depth: int = MAX_DEPTH) -> Any | None:
    """The JSON value in ``path`` (module docstring); None when the file does not exist."""
    raw = read_bounded(path, max_bytes=max_bytes, what=what, error=error)
    if raw is None:
        return None
    text = decode_utf8(raw, source=str(path), error=error)
    return parse_json(text, source=str(path), error=error, max_depth=max_depth)
