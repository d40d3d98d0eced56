"""ArduPilot DataFlash: the log's index built by numpy (the fast path of ``_dataflash``).

A DataFlash log is a chain of messages ``A3 95 <type> <body>``, each ``FMT``-described
type of a fixed length. pymavlink's ``DFReader_binary`` walks that chain message by
message; here the chain is found over the whole file at once:

1. every candidate header (the two bytes ``A3 95``) by a numpy comparison, a block of
   the file at a time (two ``uint16`` views: even and odd offsets);
2. the lengths from the candidate ``FMT`` messages (type 128, 89 bytes);
3. each candidate's successor (its offset + its type's length): runs of candidates
   whose successor is the next candidate are taken whole; only where a payload
   happens to hold ``A3 95`` (a false candidate) does the walk step, once per such
   place, from the end of a run to the next message;
4. the chain's own ``FMT`` messages are decoded with pymavlink's ``DFFormat`` (the
   reference for what a format letter means) and checked against the lengths used.

The result, :class:`FastLog`, has the attributes of ``DFReader_binary`` the reader
uses (``formats``, ``name_to_id``, ``offsets``, ``data_map``, ``data_len``).
Anything this does not cover raises :class:`Fallback` with the reason, and the reader
uses pymavlink: bytes that are not a message header between messages (a corrupt
region, which pymavlink skips a byte at a time), a message type with no ``FMT`` before
it, an ``FMT`` redefining a type's length, a length under 3 bytes, a format letter
pymavlink refuses, and more than :data:`MAX_STEPS` places to step over.
"""

from __future__ import annotations

import contextlib
import mmap
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_common import Fallback

__all__ = ["Fallback", "FastLog", "open_fast"]

HEAD1, HEAD2 = 0xA3, 0x95
FMT_TYPE, FMT_LEN = 0x80, 89
_BLOCK = 1 << 20  # bytes compared per numpy pass (1 MiB: its mask stays in the cache)
MAX_STEPS = 1 << 16
"""Most places the walk steps over (false candidates); more: pymavlink's walk."""
_FMT_BODY = np.dtype([("type", "u1"), ("length", "u1"), ("name", "S4"), ("format", "S16"),
                      ("columns", "S64")])
IntArray = NDArray[np.int64]


class FastLog:
    """What ``_dataflash`` reads of pymavlink's ``DFReader_binary``, built by numpy."""

    def __init__(self, fh: Any, data_map: mmap.mmap, formats: dict[int, Any],
                 name_to_id: dict[str, int], offsets: list[IntArray]) -> None:
        self._fh = fh
        self.data_map = data_map
        self.data_len = len(data_map)
        self.formats = formats
        self.name_to_id = name_to_id
        self.offsets: list[IntArray] | None = offsets

    def close(self) -> None:
        _close(self._fh, self.data_map)


def _close(fh: Any, data: mmap.mmap) -> None:
    """Close the map and the file; a map numpy still looks into (an exception's
    frames) is left to the garbage collector."""
    with contextlib.suppress(BufferError):
        data.close()
    fh.close()


def candidates(buf: NDArray[np.uint8]) -> IntArray:
    """Offsets of every ``A3 95`` pair in ``buf`` (ascending): the ``A3`` bytes by one
    comparison a block at a time, then the byte after each."""
    found: list[IntArray] = []
    last = len(buf) - 1  # a pair needs the byte after
    for start in range(0, last, _BLOCK):
        head = np.flatnonzero(buf[start:min(start + _BLOCK, last)] == HEAD1)
        head += start
        found.append(head[buf[head + 1] == HEAD2])
    return np.concatenate(found) if found else np.zeros(0, np.int64)


def _fmt_lengths(buf: NDArray[np.uint8], offs: IntArray) -> NDArray[np.int64]:
    """Length per type (-1 unknown) from the ``FMT`` messages at ``offs``: the first
    of each type; ``FMT`` itself is 89 bytes."""
    lengths = np.full(256, -1, dtype=np.int64)
    lengths[FMT_TYPE] = FMT_LEN
    body = _fmt_bodies(buf, offs)
    for t, n in zip(body["type"].tolist(), body["length"].tolist(), strict=True):
        if lengths[t] == -1:
            lengths[t] = n
    return lengths


def _fmt_bodies(buf: NDArray[np.uint8], offs: IntArray) -> NDArray[np.void]:
    offs = offs[offs + FMT_LEN <= len(buf)]
    rows = buf[offs[:, None] + np.arange(3, FMT_LEN, dtype=np.int64)]
    return rows.view(_FMT_BODY)[:, 0] if len(offs) else np.zeros(0, _FMT_BODY)


def chain(cand: IntArray, types: NDArray[np.uint8], lengths: NDArray[np.int64],
          data_len: int) -> IntArray | slice:
    """Indices into ``cand`` of the messages chained from offset 0 (pymavlink's walk
    on a log without corrupt regions), a slice when they are one run. Raises
    :class:`Fallback` where that walk would skip bytes or stop at an unknown type
    before the end."""
    n = len(cand)
    if n == 0 or cand[0] != 0:
        raise Fallback("the file does not start with a DataFlash message header")
    short = (lengths >= 0) & (lengths < 3)
    if bool(short.any()) and bool(np.any(short[types])):
        raise Fallback("a FMT message gives a length under 3 bytes")
    size = lengths[types]
    succ = cand + size
    ok = np.zeros(n, dtype=bool)
    ok[:-1] = (size[:-1] > 0) & (succ[:-1] == cand[1:])
    breaks = np.flatnonzero(~ok)  # the last index of each run; n - 1 always among them
    segments: list[tuple[int, int]] = []
    i = 0
    for _ in range(MAX_STEPS):
        if size[i] < 0:
            raise Fallback(f"message type {int(types[i])} at byte {int(cand[i])} has no FMT "
                           "before it")
        j = int(breaks[np.searchsorted(breaks, i)])
        segments.append((i, j + 1))
        ofs = int(succ[j])
        if ofs + 3 >= data_len:  # the end (pymavlink: while ofs + 3 < data_len)
            break
        i = int(np.searchsorted(cand, ofs))
        if i == n:  # no header after: pymavlink skips the bytes to the end
            break
        if cand[i] != ofs:
            raise Fallback(f"bytes at {ofs} are not a message header (a corrupt region)")
    else:
        raise Fallback(f"more than {MAX_STEPS} places to step over")
    if len(segments) == 1:  # the usual log: one run, no index array to build
        a, b = segments[0]
        while b > a and cand[b - 1] + 3 >= data_len:
            b -= 1
        return slice(a, b)
    idx = np.concatenate([np.arange(a, b, dtype=np.int64) for a, b in segments])
    keep = cand[idx] + 3 < data_len
    out: IntArray = idx[keep]
    return out


def _formats(buf: NDArray[np.uint8], fmt_offs: IntArray, lengths: NDArray[np.int64],
             first_use: dict[int, int]) -> tuple[dict[int, Any], dict[str, int]]:
    """pymavlink's formats from the chain's ``FMT`` messages (``DFFormat``), checked
    against the lengths the chain was walked with."""
    from pymavlink.DFReader import DFFormat

    formats: dict[int, Any] = {FMT_TYPE: DFFormat(FMT_TYPE, "FMT", FMT_LEN, "BBnNZ",
                                                  "Type,Length,Name,Format,Columns")}
    name_to_id: dict[str, int] = {}
    for ofs, row in zip(fmt_offs.tolist(), _fmt_bodies(buf, fmt_offs), strict=False):
        t, n = int(row["type"]), int(row["length"])
        if n != lengths[t]:
            raise Fallback(f"FMT at byte {ofs} gives type {t} length {n}, not "
                           f"{int(lengths[t])}")
        if t != FMT_TYPE and first_use.get(t, ofs + 1) < ofs:
            raise Fallback(f"message type {t} is used before its FMT (byte {ofs})")
        try:
            f = DFFormat(t, _text(row["name"]), n, _text(row["format"]),
                         _text(row["columns"]), oldfmt=formats.get(t))
        except Exception as exc:  # an unsupported format letter
            raise Fallback(f"FMT at byte {ofs}: {exc}") from exc
        formats[t] = f
        name_to_id[f.name] = f.type
    return formats, name_to_id


def _text(b: Any) -> str:
    """pymavlink's ``null_term`` of a struct ``s`` field."""
    s: str = bytes(b).decode(errors="backslashreplace")
    return s.split("\0", 1)[0]


def open_fast(path: Path) -> FastLog:
    """The log at ``path`` indexed by numpy; :class:`Fallback` when not covered."""
    try:
        fh = path.open("rb")
    except OSError as exc:
        raise Fallback(f"cannot open: {exc.strerror}") from exc
    try:
        data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError) as exc:  # an empty file
        fh.close()
        raise Fallback(f"cannot map: {exc}") from exc
    try:
        return _index(fh, data)
    except BaseException:
        _close(fh, data)
        raise


def _index(fh: Any, data: mmap.mmap) -> FastLog:
    buf = np.frombuffer(data, dtype=np.uint8)
    cand = candidates(buf)
    cand = cand[:int(np.searchsorted(cand, len(buf) - 2))]  # ascending: a header's type byte
    types = buf[2:][cand]  # the type byte of each
    lengths = _fmt_lengths(buf, cand[types == FMT_TYPE])
    for attempt in (0, 1):
        idx = chain(cand, types, lengths, len(buf))
        on = cand[idx]
        t_on = types[idx]
        counts = np.bincount(t_on, minlength=256)
        fmt_offs = on[t_on == FMT_TYPE]
        chained = _fmt_lengths(buf, fmt_offs)
        used = np.flatnonzero(counts)
        if np.array_equal(chained[used], lengths[used]) and np.all(chained[used] >= 0):
            break
        if attempt:
            raise Fallback("the FMT messages on the chain disagree with the lengths")
        lengths = chained  # a false FMT candidate set a length: walk with the chain's
    order = np.argsort(t_on, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(counts)])
    by_type = on[order]
    first_use = {int(t): int(by_type[bounds[t]]) for t in used}
    formats, name_to_id = _formats(buf, fmt_offs, lengths, first_use)
    offsets = [by_type[bounds[t]:bounds[t + 1]] for t in range(256)]
    return FastLog(fh, data, formats, name_to_id, offsets)
