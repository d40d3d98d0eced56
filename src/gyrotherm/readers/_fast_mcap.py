"""An indexed MCAP file's messages, a chunk at a time, by numpy (the fast path of
``_rosbag`` for ``.mcap`` files).

The summary section (found from the footer) lists the schemas, the channels and a
``ChunkIndex`` per chunk; each chunk is followed by a ``MessageIndex`` per channel:
(log time, offset) pairs, one numpy array. The message records at those offsets are
checked (opcode, length, channel) and their payloads handed to :mod:`._fast_cdr` as
(start, size) arrays into the chunk's bytes. Each chunk is read (``os.pread``: no map
of the file, whose touched pages would count as resident memory), decompressed and its
CRC checked by rosbags' own ``decompress``. Messages are ordered as rosbags yields
them: by log time, then the chunk's offset, then the record's (messages outside their
chunk's declared time range dropped, as rosbags does).

A file without a summary or chunk index, a channel not CDR, several channels on one
topic, or any record out of bounds raises :class:`Fallback` (rosbags reads it).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_common import Fallback, field_at

MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE = 0x02, 0x03, 0x04, 0x05
_OP_MESSAGE_INDEX, _OP_CHUNK_INDEX = 0x07, 0x08
_MAX_CHUNK = 1 << 28  # bytes: a larger declared chunk is not decompressed here
_MAX_SUMMARY = 1 << 28  # bytes of summary section read at most
IntArray = NDArray[np.int64]
_RECORD = np.dtype({"names": ["op", "length", "channel", "log_time"],
                    "formats": ["u1", "<u8", "<u2", "<u8"], "offsets": [0, 1, 9, 15],
                    "itemsize": 23})
"""A Message record's opcode, length, channel id and log time."""


@dataclass
class Channel:
    id: int
    topic: str
    schema: str
    encoding: str


@dataclass
class ChunkIndex:
    start_time: int
    end_time: int
    offset: int
    length: int
    message_index: dict[int, int]  # channel id → offset of its MessageIndex record
    compression: str
    compressed_size: int
    uncompressed_size: int


@dataclass
class Summary:
    channels: dict[int, Channel]
    chunks: list[ChunkIndex]


class Source:
    """The file, read where asked (``os.pread``): no map of the whole file, whose pages
    would count in the process's resident memory (an hour of MCAP is 1.3 GB)."""

    def __init__(self, fh: BinaryIO) -> None:
        self.fd = fh.fileno()
        self.size = os.fstat(self.fd).st_size

    def read(self, offset: int, n: int) -> bytes:
        if offset < 0 or n < 0 or offset + n > self.size:
            raise Fallback(f"an MCAP record runs past the end of the file at byte {offset}")
        data = os.pread(self.fd, n, offset)
        if len(data) != n:
            raise Fallback(f"a short read at byte {offset}")
        return data

    def cursor(self, offset: int, n: int) -> _Cursor:
        return _Cursor(self.read(offset, n), offset)


class _Cursor:
    """Little-endian fields of bytes read from the file at ``base``."""

    def __init__(self, data: bytes, base: int) -> None:
        self.data, self.base, self.pos = data, base, 0

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.data):
            raise Fallback(f"an MCAP record runs past its end at byte {self.base + self.pos}")
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def u(self, fmt: str) -> int:
        value: int = struct.unpack(fmt, self.take(struct.calcsize(fmt)))[0]
        return value

    def text(self) -> str:
        try:
            return self.take(self.u("<I")).decode()
        except UnicodeDecodeError as exc:
            raise Fallback("an MCAP string not UTF-8") from exc

    def record(self) -> tuple[int, _Cursor]:
        """The next record: its opcode and a cursor over its body."""
        op, n = self.u("<B"), self.u("<Q")
        at = self.base + self.pos
        return op, _Cursor(self.take(n), at)


def summary(src: Source) -> Summary:
    """Channels (with their schema's name) and chunk indexes of the file."""
    size = src.size
    if size < 2 * len(MAGIC) + 29 or src.read(0, 8) != MAGIC or src.read(size - 8, 8) != MAGIC:
        raise Fallback("not a complete MCAP file (magic at both ends)")
    foot = src.cursor(size - 8 - 29, 29)
    if foot.u("<B") != _OP_FOOTER or foot.u("<Q") != 20:
        raise Fallback("no MCAP footer")
    start = foot.u("<Q")
    if start == 0 or not 8 <= start <= size - 8 - 29 or size - 8 - 29 - start > _MAX_SUMMARY:
        raise Fallback("an MCAP file without a (readable) summary section")
    cur = src.cursor(start, size - 8 - 29 - start)
    schemas: dict[int, str] = {}
    channels: dict[int, Channel] = {}
    chunks: list[ChunkIndex] = []
    while cur.pos < len(cur.data):
        op, rec = cur.record()
        if op == _OP_SCHEMA:
            sid = rec.u("<H")
            schemas[sid] = rec.text()
        elif op == _OP_CHANNEL:
            cid, sid = rec.u("<H"), rec.u("<H")
            topic, encoding = rec.text(), rec.text()
            channels[cid] = Channel(cid, topic, schemas.get(sid, "__schemaless__"), encoding)
        elif op == _OP_CHUNK_INDEX:
            times = rec.u("<Q"), rec.u("<Q")
            where = rec.u("<Q"), rec.u("<Q")
            raw = rec.take(rec.u("<I"))
            if len(raw) % 10:
                raise Fallback("an MCAP chunk index with a bad message-index map")
            index = dict(struct.iter_unpack("<HQ", raw))
            rec.u("<Q")  # message_index_length
            comp = rec.text()
            chunks.append(ChunkIndex(*times, *where, index, comp, rec.u("<Q"), rec.u("<Q")))
    if not chunks:
        raise Fallback("an MCAP file without a chunk index")
    chunks.sort(key=lambda c: c.offset)
    return Summary(channels, chunks)


@dataclass
class Plan:
    """A chunk holding wanted channels: where its records are in the file, how they
    are stored, and each wanted channel's record offsets (from its message index)."""

    chunk: ChunkIndex
    data_at: int  # file offset of the (compressed) records
    crc: int
    offs: dict[int, IntArray]


@dataclass
class Indexed:
    """One channel's indexed messages of one chunk, before they are checked: record
    offsets into ``buf`` (several chunks' records), the bounds of the chunk's records
    in ``buf``, and the chunk."""

    buf: NDArray[np.uint8]
    offs: IntArray
    lo: int
    hi: int
    chunk: ChunkIndex


@dataclass
class Messages:
    """Checked messages of one channel (of one or more chunks sharing ``buf``):
    payload (start, size) into ``buf`` and log times, in file order."""

    buf: NDArray[np.uint8]
    start: IntArray
    size: IntArray
    log_time: IntArray


def plan(src: Source, chunk: ChunkIndex, wanted: list[int]) -> Plan | None:
    """The chunk's header checked against its index and the ``wanted`` channels'
    message indexes; None when it holds none of them."""
    present = [c for c in wanted if c in chunk.message_index]
    if not present:
        return None
    head = src.cursor(chunk.offset, min(9 + 40 + len(chunk.compression.encode()),
                                        src.size - chunk.offset))
    if head.u("<B") != 0x06:
        raise Fallback(f"no MCAP chunk at byte {chunk.offset}")
    head.take(8 + 16)  # record length, message start/end time
    usize, crc = head.u("<Q"), head.u("<I")
    comp = head.text()
    csize = head.u("<Q")
    if (comp, usize, csize) != (chunk.compression, chunk.uncompressed_size,
                                chunk.compressed_size) or usize > _MAX_CHUNK:
        raise Fallback(f"an MCAP chunk disagreeing with its index at byte {chunk.offset}")
    at = head.base + head.pos
    if at + csize > src.size:
        raise Fallback(f"an MCAP chunk cut short at byte {chunk.offset}")
    return Plan(chunk, at, crc, {c: _message_index(src, chunk.message_index[c], c, usize)
                                 for c in present})


def load(src: Source, plans: list[Plan]) -> list[tuple[int, Indexed]]:
    """The records of ``plans`` (chunks in file order) in one buffer: one read of the
    file's span when none is compressed, else each chunk decompressed and joined; each
    chunk's size and CRC checked by rosbags' ``decompress``."""
    from rosbags.rosbag2.storage_mcap import decompress

    def checked_raw(raw: bytes | memoryview, p: Plan) -> bytes | memoryview:
        c = p.chunk
        try:
            out: bytes | memoryview = decompress(raw, c.compression,  # type: ignore[arg-type]
                                                 c.uncompressed_size, p.crc)
        except Exception as exc:  # checksum, size, codec: rosbags says what
            raise Fallback(f"MCAP chunk at byte {c.offset}: {exc}") from exc
        if len(out) != c.uncompressed_size:
            raise Fallback(f"an MCAP chunk cut short at byte {c.offset}")
        return out

    if all(not p.chunk.compression for p in plans):
        first, last = plans[0], plans[-1]
        span = src.read(first.data_at, last.data_at + last.chunk.compressed_size
                        - first.data_at)
        view = memoryview(span)
        bases = [p.data_at - first.data_at for p in plans]
        for p, base in zip(plans, bases, strict=True):
            checked_raw(view[base:base + p.chunk.compressed_size], p)
        buf = np.frombuffer(span, dtype=np.uint8)
    else:
        raws = [checked_raw(src.read(p.data_at, p.chunk.compressed_size), p) for p in plans]
        bases = np.concatenate([[0], np.cumsum([len(r) for r in raws])]).tolist()[:-1]
        buf = np.frombuffer(b"".join(raws), dtype=np.uint8)
    return [(cid, Indexed(buf, offs + base, base, base + p.chunk.uncompressed_size, p.chunk))
            for p, base in zip(plans, bases, strict=True) for cid, offs in p.offs.items()]


def _message_index(src: Source, at: int, cid: int, usize: int) -> IntArray:
    cur = src.cursor(at, min(15, src.size - at))
    if cur.u("<B") != _OP_MESSAGE_INDEX:
        raise Fallback(f"no MCAP message index at byte {at}")
    cur.u("<Q")
    if cur.u("<H") != cid:
        raise Fallback(f"an MCAP message index for another channel at byte {at}")
    n = cur.u("<I")
    if n % 16 or n > 16 * (usize // 31 + 1):  # at most one message per 31 bytes
        raise Fallback(f"a bad MCAP message index at byte {at}")
    pairs = np.frombuffer(src.read(at + 15, n), dtype="<u8").reshape(-1, 2)
    if np.any(pairs[:, 1] >= 1 << 62):
        raise Fallback(f"an MCAP message index out of its chunk at byte {at}")
    offs: IntArray = pairs[:, 1].astype(np.int64)
    return offs


def checked(cid: int, group: list[Indexed]) -> Messages:
    """The messages of ``group`` (chunks sharing one buffer), their records checked
    against the chunks' bounds: opcode, channel, length."""
    buf = group[0].buf
    counts = [len(g.offs) for g in group]

    def each(values: list[int]) -> IntArray:
        return np.repeat(np.asarray(values, dtype=np.int64), counts)

    offs = np.concatenate([g.offs for g in group])
    lo, hi = each([g.lo for g in group]), each([g.hi for g in group])
    where = f"(chunks from byte {group[0].chunk.offset})"
    if np.any(offs < lo) or np.any(offs + 31 > hi) or \
            (len(offs) > 1 and bool(np.any(np.diff(offs) <= 0))):
        raise Fallback(f"an MCAP message index out of its chunk {where}")
    rec = field_at(buf, offs, _RECORD)  # one gather for the record's fixed fields
    if np.any(rec["op"] != _OP_MESSAGE) or np.any(rec["channel"] != cid):
        raise Fallback(f"an MCAP message index not pointing at its messages {where}")
    length = rec["length"]
    if np.any(length < 22) or np.any(length > hi - offs - 9):
        raise Fallback(f"an MCAP message record out of its chunk {where}")
    log_time = rec["log_time"]
    if np.any(log_time >= 1 << 63):
        raise Fallback("an MCAP log time beyond int64")
    t = log_time.astype(np.int64)
    keep = (t >= each([g.chunk.start_time for g in group])) & \
        (t <= each([g.chunk.end_time for g in group]))
    if bool(keep.all()):
        return Messages(buf, offs + 31, length.astype(np.int64) - 22, t)
    return Messages(buf, offs[keep] + 31, length[keep].astype(np.int64) - 22, t[keep])
