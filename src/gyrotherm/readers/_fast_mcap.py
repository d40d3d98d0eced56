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
from collections.abc import Iterator
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
class Indexed:
    """One channel's indexed messages of one chunk, before they are checked: record
    offsets into ``buf`` (the chunk's records, or several chunks' joined), the bounds of
    the chunk's records in ``buf``, and the chunk."""

    buf: NDArray[np.uint8]
    offs: IntArray
    lo: int
    hi: int
    chunk: ChunkIndex


@dataclass
class Messages:
    """Checked messages of one channel (of one or more chunks sharing ``buf``):
    payload (start, size) into ``buf``, log times, and the sort key after the log
    time (chunk offset, record offset)."""

    buf: NDArray[np.uint8]
    start: IntArray
    size: IntArray
    log_time: IntArray
    chunk: IntArray
    record: IntArray


def chunk_messages(src: Source, chunk: ChunkIndex, wanted: list[int]
                   ) -> Iterator[tuple[int, Indexed]]:
    """(channel id, its indexed messages) for each ``wanted`` channel in ``chunk``,
    the chunk's records read (and decompressed, its CRC checked) once for all."""
    from rosbags.rosbag2.storage_mcap import decompress

    present = [c for c in wanted if c in chunk.message_index]
    if not present:
        return
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
    try:
        raw = decompress(src.read(head.base + head.pos, csize), comp, usize, crc)
    except Fallback:
        raise
    except Exception as exc:  # checksum, size, codec: rosbags says what
        raise Fallback(f"MCAP chunk at byte {chunk.offset}: {exc}") from exc
    if len(raw) != usize:
        raise Fallback(f"an MCAP chunk cut short at byte {chunk.offset}")
    buf = np.frombuffer(raw, dtype=np.uint8)
    for cid in present:
        offs = _message_index(src, chunk.message_index[cid], cid, usize)
        yield cid, Indexed(buf, offs, 0, usize, chunk)


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
    if np.any(buf[offs] != _OP_MESSAGE) or \
            np.any(field_at(buf, offs + 9, np.dtype("<u2")) != cid):
        raise Fallback(f"an MCAP message index not pointing at its messages {where}")
    length = field_at(buf, offs + 1, np.dtype("<u8"))
    if np.any(length < 22) or np.any(length > hi - offs - 9):
        raise Fallback(f"an MCAP message record out of its chunk {where}")
    log_time = field_at(buf, offs + 15, np.dtype("<u8"))
    if np.any(log_time >= 1 << 63):
        raise Fallback("an MCAP log time beyond int64")
    t = log_time.astype(np.int64)
    keep = (t >= each([g.chunk.start_time for g in group])) & \
        (t <= each([g.chunk.end_time for g in group]))
    chunk = each([g.chunk.offset for g in group])
    return Messages(buf, offs[keep] + 31, length[keep].astype(np.int64) - 22, t[keep],
                    chunk[keep], (offs - lo)[keep])
