"""PX4 ULog: the subscribed topics' data messages decoded by numpy (the fast path of
``_ulog``).

A ULog is a 16-byte header and a chain of messages ``uint16 size, uint8 type,
payload``. pyulog reads the header and the definitions section (formats, info,
parameters: small) as it always does (``parse_header_only``); the data section is
walked here:

* data messages (``D``: ``uint16 msg_id`` + the topic's fields) of a subscribed topic
  are found in one scan from the first data message on, a MiB at a time (what a block
  yields stays in the cache): every ``D`` byte whose size and ``msg_id`` fit a
  subscription (from the ``A`` messages, pyulog's ``_MessageAddLogged``). Runs of
  such candidates that chain (each one's offset + 3 + size is the next) are taken
  whole; every other message (``A``, info, logging, sync, dropouts, data of topics not
  read) is stepped over one at a time;
* each subscription's fields (pyulog's numpy dtype for it; only those the caller
  names in ``fields``) are then gathered from its messages' offsets: one numpy gather
  per field, or a strided view, copied a block at a time, when the messages are
  evenly spaced.

The result has what ``_ulog`` reads of pyulog's ``ULog`` (``data_list`` of objects with
``name``, ``multi_id``, ``data``; ``msg_info_dict``; ``file_corruption``) and the bytes
of a message cut by the end of the file. What this does not cover raises
:class:`Fallback` and pyulog reads the file: appended data, anything pyulog prints or
flags as corrupt while reading the definitions, an unknown message type, a data
message of an unsubscribed id or of another size than its topic's, a remove-logged
(``R``) message, more than :data:`MAX_STEPS` messages to step over.
"""

from __future__ import annotations

import contextlib
import io
import mmap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_common import Fallback, columns, fields_at

HEADER = 16
MAX_STEPS = 1 << 20
"""Most messages stepped over one at a time (not data of the topics read)."""
_SKIP = {ord(c) for c in "IMPQLCSO"}  # read or skipped one at a time
IntArray = NDArray[np.int64]


@dataclass
class Topic:
    """One subscription's data, as pyulog's ``ULog.Data``: ``data`` maps each field
    (pyulog's flattened names) to its column."""

    name: str
    multi_id: int
    msg_id: int
    data: dict[str, NDArray[Any]]


@dataclass
class FastULog:
    data_list: list[Topic]
    msg_info_dict: dict[str, Any]
    bytes_cut_at_end: int
    file_corruption: bool = False
    dropouts: list[Any] = field(default_factory=list)


def _header_only(path: Path, topics: list[str]) -> Any:
    from pyulog import ULog

    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said):
            ulog = ULog(str(path), topics, parse_header_only=True)
    except Exception as exc:  # pyulog says why, on the library path
        raise Fallback(f"pyulog refuses the header: {exc}") from exc
    if said.getvalue().strip() or ulog.file_corruption:
        raise Fallback("pyulog reports the definitions damaged")
    if ulog.has_data_appended and any(ulog._appended_offsets):
        raise Fallback("appended data")
    return ulog


Fields = Mapping[str, Sequence[str]]
"""Per topic, the fields to decode; ``"a|b"`` is the first of ``a``, ``b`` the topic has."""


def load(path: Path, topics: list[str], *, fields: Fields | None = None) -> FastULog:
    """The ``topics`` of the ULog at ``path``; :class:`Fallback` when not covered.

    ``fields`` (per topic) limits what is decoded to what the caller reads (a topic
    that lacks one of them, or is not in ``fields``, gets all its fields, as pyulog
    gives them)."""
    head = _header_only(path, topics)
    with path.open("rb") as fh:
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if path.stat().st_size else None
        if mm is None:
            raise Fallback("an empty file")
        try:
            return _load(np.frombuffer(mm, dtype=np.uint8), head, topics, fields or {})
        finally:
            with contextlib.suppress(BufferError):
                mm.close()


_SCAN = 1 << 20
"""Bytes scanned per block for data messages (their candidates stay in the cache)."""
_EMPTY = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64))


class _Taken:
    """The candidates a batch takes (offset, ``msg_id``, offset after), appended
    block by block into one allocation (grown by doubling): no list to join."""

    def __init__(self) -> None:
        self.n = 0
        self.at, self.succ = np.empty(0, np.int64), np.empty(0, np.int64)
        self.ids: NDArray[np.uint16] = np.empty(0, np.uint16)

    def reserve(self, capacity: int) -> None:
        if capacity > len(self.at):
            self.at, self.ids, self.succ = (self._grown(c, capacity)
                                            for c in (self.at, self.ids, self.succ))

    def _grown(self, column: NDArray[Any], capacity: int) -> NDArray[Any]:
        grown = np.empty(capacity, column.dtype)  # pages untouched until written
        grown[:self.n] = column[:self.n]
        return grown

    def take(self, keep: NDArray[np.bool_], at: IntArray, ids: IntArray, size: IntArray
             ) -> None:
        m = int(np.count_nonzero(keep))
        if self.n + m > len(self.at):
            self.reserve(max(2 * len(self.at), self.n + m))
        part = slice(self.n, self.n + m)
        np.compress(keep, at, out=self.at[part])
        np.compress(keep, ids, out=self.ids[part])
        succ = self.succ[part]
        np.compress(keep, size, out=succ)
        succ += self.at[part]
        succ += 3
        self.n += m

    def columns(self) -> tuple[IntArray, NDArray[np.uint16], IntArray]:
        return self.at[:self.n], self.ids[:self.n], self.succ[:self.n]


class _Candidates:
    """The data messages of the subscribed ids (read or not), from where the walk is
    on, and where their runs of chained messages end. Subscriptions are added in
    batches (the ``A`` messages come together), applied at the next data message.

    The file is scanned once, at the first batch, from there on and :data:`_SCAN`
    bytes at a time: every ``D`` byte, its message's size and ``msg_id`` (one gather of
    the 5-byte header as an unaligned ``uint64``), matched against the batch. Every
    ``A`` of a batch lies before that point, so no candidate can precede its
    subscription. What no subscription took (``D`` bytes inside payloads, ids not yet
    subscribed) is kept for the later batches."""

    def __init__(self, buf: NDArray[np.uint8]) -> None:
        self.buf = buf
        n = len(buf)
        self.i64: IntArray = np.ndarray(shape=(max(n - 7, 0),), dtype="<i8", buffer=buf,
                                        strides=(1,))
        self.scanned = False
        self.left: IntArray = _EMPTY[0]  # offsets no subscription took (yet)
        self.flexible = False  # a pending subscription with two sizes, or any size
        # sizes a pending subscription's data may have: -1 any (≥ 2), -2 none (not pending)
        self.sizes = np.full((2, 1 << 16), -2, dtype=np.int64)
        self.pending = False
        self.at, self.succ = _EMPTY[:2]
        self.at_ids: NDArray[np.uint16] = np.zeros(0, np.uint16)
        self.breaks = np.zeros(0, np.int64)

    def add(self, msg_id: int, sizes: tuple[int, int] | None) -> None:
        self.sizes[:, msg_id] = sizes if sizes is not None else (-1, -1)
        self.pending = True

    def _match(self, at: IntArray, ids: IntArray, size: IntArray, out: _Taken,
               left: list[IntArray]) -> None:
        """The candidates the pending batch takes go to ``out``; the others' offsets
        to ``left``."""
        lo = self.sizes[0][ids]
        keep = size == lo
        if self.flexible:
            keep |= (size == self.sizes[1][ids]) | ((lo == -1) & (size >= 2))
        left.append(at[~keep])
        out.take(keep, at, ids, size)

    def _heads(self, at: IntArray) -> tuple[IntArray, IntArray]:
        """The ``msg_id`` and payload size of the messages at ``at``."""
        head = self.i64[at]  # size (2), type (1), msg_id (2), the next 3 bytes
        return (head >> 24) & 0xFFFF, head & 0xFFFF

    def _scan(self, pos: int, out: _Taken, left: list[IntArray]) -> None:
        n = len(self.buf)
        for start in range(pos + 2, n, _SCAN):
            at = np.flatnonzero(self.buf[start:start + _SCAN] == ord("D"))
            at += start - 2
            if start + _SCAN > n - 8:  # the last bytes: a header the file cuts
                at = at[at + 8 <= n]
            ids, size = self._heads(at)
            if start + _SCAN + (1 << 16) > n:  # a message the file cuts
                whole = at + 3 + size <= n
                at, ids, size = at[whole], ids[whole], size[whole]
            if start == pos + 2:  # room for as many per block as in the first
                out.reserve(len(at) * (1 + (n - start) // _SCAN) * 9 // 8)
            self._match(at, ids, size, out, left)

    def _apply(self, pos: int) -> None:
        left: list[IntArray] = [_EMPTY[0]]
        self.flexible = bool(np.any((self.sizes[0] != self.sizes[1]) | (self.sizes[0] == -1)))
        out = _Taken()
        if self.scanned:
            at = self.left[self.left >= pos]
            self._match(at, *self._heads(at), out, left)
        else:
            self._scan(pos, out, left)
            self.scanned = True
        self.left = np.concatenate(left)
        new, new_ids, new_succ = out.columns()
        self.sizes[:] = -2
        self.pending = False
        if len(self.at):  # disjoint (an id is subscribed once), both sorted: a merge
            order = np.argsort(np.concatenate([self.at, new]), kind="stable")
            self.at = np.concatenate([self.at, new])[order]
            self.at_ids = np.concatenate([self.at_ids, new_ids])[order]
            self.succ = np.concatenate([self.succ, new_succ])[order]
        else:
            self.at, self.at_ids, self.succ = new, new_ids, new_succ
        ok = self.succ[:-1] == self.at[1:]
        self.breaks = np.append(np.flatnonzero(~ok), len(self.at) - 1)

    def run_at(self, pos: int) -> tuple[int, int, int] | None:
        """The run of chained candidates from ``pos``: its first and last index in
        ``at`` and ``at_ids``, and the offset after it. ``at`` is replaced (not
        changed) when a later batch is applied."""
        if self.pending and self.buf[pos + 2] == ord("D"):
            self._apply(pos)
        i = int(np.searchsorted(self.at, pos))
        if i == len(self.at) or self.at[i] != pos:
            return None
        j = int(self.breaks[np.searchsorted(self.breaks, i)])
        return i, j, int(self.succ[j])


class _Runs:
    """The runs the walk took, as index ranges of the candidates: one view when they
    follow each other (the usual case), joined otherwise."""

    def __init__(self, cands: _Candidates) -> None:
        self.cands = cands
        self.parts: list[tuple[IntArray, NDArray[np.uint16]]] = []
        self.span: tuple[IntArray, int, int] | None = None  # at, first, last

    def add(self, i: int, j: int) -> None:
        at = self.cands.at
        if self.span is not None and self.span[0] is at and self.span[2] + 1 == i:
            self.span = (at, self.span[1], j)
            return
        self._close()
        self.span = (at, i, j)

    def _close(self) -> None:
        if self.span is not None:
            _, i, j = self.span
            self.parts.append((self.cands.at[i:j + 1], self.cands.at_ids[i:j + 1]))

    def columns(self) -> tuple[IntArray, NDArray[np.uint16]]:
        self._close()
        self.span = None
        if len(self.parts) == 1:
            return self.parts[0]
        if not self.parts:
            return np.zeros(0, np.int64), np.zeros(0, np.uint16)
        return (np.concatenate([p[0] for p in self.parts]),
                np.concatenate([p[1] for p in self.parts]))


def _names(dtype: np.dtype[Any], wanted: Sequence[str] | None) -> tuple[str, ...]:
    """The fields of ``dtype`` to decode: ``wanted`` (first present of each ``a|b``),
    or all when it is None or one is absent."""
    every = tuple(dtype.names or ())
    picked = []
    for spec in wanted or ():
        name = next((n for n in spec.split("|") if n in every), None)
        if name is None:
            return every
        picked.append(name)
    return tuple(picked) if wanted is not None else every


def _columns(buf: NDArray[np.uint8], offs: IntArray, sub: Any,
             names: tuple[str, ...]) -> dict[str, NDArray[Any]]:
    """The fields ``names`` of the data messages at ``offs`` (ascending, one chain:
    they do not overlap). When every message has the topic's one size ``L`` and they
    span ``(n - 1)·L`` bytes, every gap is ``L`` (none is shorter): a strided view."""
    length = 3 + 2 + sub.dtype.itemsize
    if len(offs) > 1 and sub.max_data_size == sub.dtype.itemsize \
            and int(offs[-1] - offs[0]) == (len(offs) - 1) * length:
        rec: NDArray[Any] = np.ndarray(shape=(len(offs),), dtype=sub.dtype, buffer=buf,
                                       offset=int(offs[0]) + 5, strides=(length,))
        return columns(rec, names)
    return fields_at(buf, offs + 5, sub.dtype, names)


def _load(buf: NDArray[np.uint8], head: Any, topics: list[str], fields: Fields
          ) -> FastULog:
    from pyulog import ULog

    end = len(buf)
    info: dict[str, Any] = dict(head.msg_info_dict)
    formats = head._message_formats
    cands = _Candidates(buf)
    subs: dict[int, Any] = {}
    filtered: set[int] = set()
    runs = _Runs(cands)
    pos, data_started = HEADER, False
    for _ in range(MAX_STEPS):
        if pos + 3 > end:
            break
        run = cands.run_at(pos)
        if run is not None:  # data of the topics read: a run at once
            runs.add(run[0], run[1])
            pos = run[2]
            continue
        size, kind = int(buf[pos]) | int(buf[pos + 1]) << 8, int(buf[pos + 2])
        if pos + 3 + size > end:
            break  # cut by the end of the file
        payload = bytes(buf[pos + 3:pos + 3 + size])
        if not data_started and kind not in (ord("A"), ord("L"), ord("C")):
            pos += 3 + size  # the definitions section, read by pyulog
            continue
        data_started = True
        if kind == ord("A"):
            try:
                sub = ULog._MessageAddLogged(payload, None, formats)
            except Exception as exc:
                raise Fallback(f"an unreadable subscription at byte {pos}") from exc
            if sub.msg_id in subs or sub.msg_id in filtered:
                raise Fallback(f"msg_id {sub.msg_id} subscribed twice")
            if sub.message_name not in topics:
                filtered.add(sub.msg_id)  # pyulog skips its data, of any size
                cands.add(sub.msg_id, None)
            else:
                subs[sub.msg_id] = sub
                cands.add(sub.msg_id, (2 + sub.dtype.itemsize, 2 + sub.max_data_size))
        elif kind == ord("D"):
            mid = int.from_bytes(payload[:2], "little") if size >= 2 else -1
            if mid not in filtered:
                raise Fallback(f"a data message at byte {pos} pyulog would flag "
                               f"(msg_id {mid}, {size} bytes)")
        elif kind == ord("I"):
            try:
                msg = ULog._MessageInfo(payload, None)
            except Exception as exc:
                raise Fallback(f"an unreadable info message at byte {pos}") from exc
            info[msg.key] = msg.value
        elif kind not in _SKIP:
            raise Fallback(f"message type {kind} at byte {pos}")
        pos += 3 + size
    else:
        raise Fallback(f"more than {MAX_STEPS} messages to step over")
    offs, ids = runs.columns()
    if len(ids) and not bool(np.all(ids[1:] >= ids[:-1])):
        order = np.argsort(ids, kind="stable")
        offs, ids = offs[order], ids[order]
    data_list = []
    for mid, sub in subs.items():
        lo, hi = (int(np.searchsorted(ids, mid, side=s)) for s in ("left", "right"))
        if hi > lo:
            names = _names(sub.dtype, fields.get(sub.message_name))
            data_list.append(Topic(sub.message_name, sub.multi_id, mid,
                                   _columns(buf, offs[lo:hi], sub, names)))
    data_list.sort(key=lambda d: (d.name, d.multi_id))
    return FastULog(data_list, info, end - pos)
