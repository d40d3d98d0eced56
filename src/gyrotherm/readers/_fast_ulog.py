"""PX4 ULog: the subscribed topics' data messages decoded by numpy (the fast path of
``_ulog``).

A ULog is a 16-byte header and a chain of messages ``uint16 size, uint8 type,
payload``. pyulog reads the header and the definitions section (formats, info,
parameters: small) as it always does (``parse_header_only``); the data section is
walked here:

* data messages (``D``: ``uint16 msg_id`` + the topic's fields) of a subscribed topic
  are found over the whole file at once: every ``D`` byte whose size and ``msg_id``
  fit a subscription (from the ``A`` messages, pyulog's ``_MessageAddLogged``). Runs of
  such candidates that chain (each one's offset + 3 + size is the next) are taken
  whole; every other message (``A``, info, logging, sync, dropouts, data of topics not
  read) is stepped over one at a time;
* each subscription's fields (pyulog's numpy dtype for it) are then gathered from its
  messages' offsets: one numpy gather per field, or a strided view when the messages
  are evenly spaced.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_common import Fallback, field_at, fields_at

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


def load(path: Path, topics: list[str]) -> FastULog:
    """The ``topics`` of the ULog at ``path``; :class:`Fallback` when not covered."""
    head = _header_only(path, topics)
    with path.open("rb") as fh:
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if path.stat().st_size else None
        if mm is None:
            raise Fallback("an empty file")
        try:
            return _load(np.frombuffer(mm, dtype=np.uint8), head, topics)
        finally:
            with contextlib.suppress(BufferError):
                mm.close()


_D_HEAD = np.dtype([("size", "<u2"), ("type", "u1"), ("id", "<u2")])


def _d_positions(buf: NDArray[np.uint8]) -> tuple[IntArray, NDArray[np.int32],
                                                  NDArray[np.uint16]]:
    """Offsets, sizes and msg_ids of every message that could be a whole ``D`` inside
    the file (found by its type byte; one gather of the 5-byte header each)."""
    found, sizes, ids = [], [], []
    for start in range(2, len(buf), 1 << 24):
        at = np.flatnonzero(buf[start:start + (1 << 24)] == ord("D")) + (start - 2)
        at = at[(at >= 0) & (at + 5 <= len(buf))].astype(np.int64)
        head = field_at(buf, at, _D_HEAD)
        size = head["size"].astype(np.int32)
        whole = at + 3 + size <= len(buf)
        found.append(at[whole])
        sizes.append(size[whole])
        ids.append(head["id"][whole])
    if not found:
        return np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.uint16)
    return np.concatenate(found), np.concatenate(sizes), np.concatenate(ids)


class _Candidates:
    """The data messages of the subscribed ids (read or not), wherever they could
    start, and where their runs of chained messages end. Subscriptions are added in
    batches (the ``A`` messages come together), applied before the next data message."""

    def __init__(self, buf: NDArray[np.uint8]) -> None:
        self.buf = buf
        self.all, self.size, self.ids = _d_positions(buf)
        self.after = np.full(1 << 16, -1, dtype=np.int64)  # subscribed at (pending)
        # sizes a pending subscription's data may have: -1 any (≥ 2), -2 none (not pending)
        self.sizes = np.full((2, 1 << 16), -2, dtype=np.int32)
        self.pending = False
        self.at = np.zeros(0, np.int64)
        self.at_ids = np.zeros(0, np.int64)
        self.breaks = np.zeros(0, np.int64)
        self.succ = np.zeros(0, np.int64)

    def add(self, msg_id: int, sizes: tuple[int, int] | None, after: int) -> None:
        self.after[msg_id] = after
        self.sizes[:, msg_id] = sizes if sizes is not None else (-1, -1)
        self.pending = True

    def _apply(self) -> None:
        lo, hi = self.sizes[0][self.ids], self.sizes[1][self.ids]
        fits = (self.size == lo) | (self.size == hi) | ((lo == -1) & (self.size >= 2))
        keep = fits & (self.all > self.after[self.ids])
        new, new_size = self.all[keep], self.size[keep]
        self.after[:] = -1
        self.sizes[:] = -2
        self.pending = False
        if len(self.at):  # disjoint (an id is subscribed once), both sorted: a merge
            order = np.argsort(np.concatenate([self.at, new]), kind="stable")
            self.at = np.concatenate([self.at, new])[order]
            self.at_ids = np.concatenate([self.at_ids, self.ids[keep].astype(np.int64)])[order]
            self.succ = np.concatenate([self.succ, new + 3 + new_size])[order]
        else:
            self.at, self.at_ids = new, self.ids[keep].astype(np.int64)
            self.succ = new + 3 + new_size
        ok = self.succ[:-1] == self.at[1:]
        self.breaks = np.append(np.flatnonzero(~ok), len(self.at) - 1)

    def run_at(self, pos: int) -> tuple[IntArray, IntArray, int] | None:
        """The run of chained candidates from ``pos``, their msg_ids and the offset
        after it."""
        if self.pending and self.buf[pos + 2] == ord("D"):
            self._apply()
        i = int(np.searchsorted(self.at, pos))
        if i == len(self.at) or self.at[i] != pos:
            return None
        j = int(self.breaks[np.searchsorted(self.breaks, i)])
        return self.at[i:j + 1], self.at_ids[i:j + 1], int(self.succ[j])


def _load(buf: NDArray[np.uint8], head: Any, topics: list[str]) -> FastULog:
    from pyulog import ULog

    end = len(buf)
    info: dict[str, Any] = dict(head.msg_info_dict)
    formats = head._message_formats
    cands = _Candidates(buf)
    subs: dict[int, Any] = {}
    filtered: set[int] = set()
    chained: list[IntArray] = []
    chained_ids: list[IntArray] = []
    pos, data_started = HEADER, False
    for _ in range(MAX_STEPS):
        if pos + 3 > end:
            break
        run = cands.run_at(pos)
        if run is not None:  # data of the topics read: a run at once
            chained.append(run[0])
            chained_ids.append(run[1])
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
                cands.add(sub.msg_id, None, pos)
            else:
                subs[sub.msg_id] = sub
                cands.add(sub.msg_id, (2 + sub.dtype.itemsize, 2 + sub.max_data_size), pos)
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
    offs = np.concatenate(chained) if chained else np.zeros(0, np.int64)
    ids = np.concatenate(chained_ids) if chained else np.zeros(0, np.int64)
    if len(ids) and not bool(np.all(ids[1:] >= ids[:-1])):
        order = np.argsort(ids, kind="stable")
        offs, ids = offs[order], ids[order]
    data_list = []
    for mid, sub in subs.items():
        lo, hi = np.searchsorted(ids, [mid, mid + 1])
        if hi > lo:
            data_list.append(Topic(sub.message_name, sub.multi_id, mid,
                                   fields_at(buf, offs[lo:hi] + 5, sub.dtype)))
    data_list.sort(key=lambda d: (d.name, d.multi_id))
    return FastULog(data_list, info, end - pos)
