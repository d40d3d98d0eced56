"""The IMU and temperature rows of an indexed ``.mcap`` file, decoded by numpy: the
fast path of ``_rosbag`` (the same rows, in the same order, as its loop over rosbags'
messages). The container is read by :mod:`._fast_mcap`, the CDR by :mod:`._fast_cdr`;
the chunks' messages are decoded a few MiB of chunks at a time (fewer numpy calls than
per chunk, still in cache).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_cdr import decode_imu, decode_temperature
from gyrotherm.readers._fast_common import Fallback
from gyrotherm.readers._fast_mcap import (
    Indexed,
    Messages,
    Source,
    checked,
    chunk_messages,
    summary,
)

IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
_GROUP = 1 << 23  # bytes of chunks decoded together (in cache, few numpy calls)
IntArray = NDArray[np.int64]


def gather(path: Path, imu_topics: list[str], temp_topics: list[str]
           ) -> tuple[dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]],
                      dict[str, NDArray[np.float64]], dict[str, int]]:
    """What ``_rosbag`` gathers with rosbags, decoded by numpy: IMU rows per (topic,
    frame_id) (stamps ns, (n, 6) ω and a, NaN where a covariance marks them absent),
    temperature rows per topic ((n, 2): stamp ns as float, °C), and per IMU topic the
    count of zero stamps (replaced by the log time)."""
    with path.open("rb") as fh:
        return _gather(Source(fh), imu_topics, temp_topics)


def _gather(src: Source, imu_topics: list[str], temp_topics: list[str]
            ) -> tuple[dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]],
                       dict[str, NDArray[np.float64]], dict[str, int]]:
    s = summary(src)
    want = {IMU_TYPE: imu_topics, TEMPERATURE_TYPE: temp_topics}
    ids: dict[int, tuple[str, str]] = {}
    for msgtype, topics in want.items():
        for topic in topics:
            chans = [c for c in s.channels.values() if c.topic == topic]
            if len(chans) != 1 or chans[0].schema != msgtype or chans[0].encoding != "cdr":
                raise Fallback(f"topic {topic!r}: not one CDR {msgtype} channel")
            ids[chans[0].id] = (topic, msgtype)
    parts: dict[int, list[_Part]] = {cid: [] for cid in ids}
    pending: list[tuple[NDArray[np.uint8], list[tuple[int, Indexed]]]] = []
    held = 0
    for chunk in s.chunks:
        found = list(chunk_messages(src, chunk, sorted(ids)))
        if not found:
            continue
        if held + chunk.uncompressed_size > _GROUP and pending:
            _flush(pending, ids, parts)
            held = 0
        pending.append((found[0][1].buf, found))
        held += chunk.uncompressed_size
    if pending:
        _flush(pending, ids, parts)
    imu: dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]] = {}
    temps: dict[str, NDArray[np.float64]] = {}
    missing: dict[str, int] = {}
    for cid, (topic, msgtype) in ids.items():
        p = _joined(parts.pop(cid))
        zero = p.stamp == 0
        if msgtype == TEMPERATURE_TYPE:
            ns = np.where(zero, p.log_time, p.stamp)
            temps[topic] = np.column_stack([ns.astype(np.float64), p.values[:, 0]])
            continue
        if zero.any():
            missing[topic] = int(np.count_nonzero(zero))
        ns = np.where(zero, p.log_time, p.stamp)
        for k, frame in enumerate(p.frames):
            sel = p.frame == k
            imu[(topic, frame)] = (ns[sel], p.values[sel])
    return imu, temps, missing


def _flush(pending: list[tuple[NDArray[np.uint8], list[tuple[int, Indexed]]]],
           ids: dict[int, tuple[str, str]], parts: dict[int, list[_Part]]) -> None:
    """Decode the pending chunks' messages: their bytes joined into one buffer (a few
    MiB: few numpy calls, still in cache), each channel's messages checked and decoded
    at once."""
    buf = np.concatenate([b for b, _ in pending]) if len(pending) > 1 else pending[0][0]
    by_channel: dict[int, list[Indexed]] = {}
    base = 0
    for b, found in pending:
        for cid, m in found:
            by_channel.setdefault(cid, []).append(
                Indexed(buf, m.offs + base, m.lo + base, m.hi + base, m.chunk))
        base += len(b)
    pending.clear()
    for cid, group in by_channel.items():
        parts[cid].append(_decode(checked(cid, group), ids[cid][1]))


@dataclass
class _Part:
    """Decoded messages of one channel (a chunk's, or all joined in rosbags' order)."""

    stamp: IntArray
    frame: NDArray[np.intp]
    frames: list[str]
    values: NDArray[np.float64]  # (n, 6) for Imu, (n, 1) for Temperature
    log_time: IntArray
    chunk: IntArray
    record: IntArray


def _decode(m: Messages, msgtype: str) -> _Part:
    if msgtype == TEMPERATURE_TYPE:
        h, temp = decode_temperature(m.buf, m.start, m.size)
        values = temp[:, None]
    else:
        cols = decode_imu(m.buf, m.start, m.size)
        h, values = cols.header, cols.values
        values[cols.rate_cov0 == -1.0, :3] = np.nan
        values[cols.accel_cov0 == -1.0, 3:] = np.nan
    return _Part(h.stamp_ns, h.frame, h.frames, values, m.log_time, m.chunk, m.record)


def _joined(parts: list[_Part]) -> _Part:
    """The chunks' parts as one, frame ids renumbered, ordered as rosbags yields them
    (log time, chunk offset, record offset)."""
    frames: list[str] = []
    codes: list[NDArray[np.intp]] = []
    for q in parts:
        for f in q.frames:
            if f not in frames:
                frames.append(f)
        remap = np.array([frames.index(f) for f in q.frames] or [0], dtype=np.intp)
        codes.append(remap[q.frame])

    def cat(arrays: list[NDArray[Any]], empty: NDArray[Any]) -> NDArray[Any]:
        return np.concatenate(arrays) if arrays else empty

    z = np.zeros(0, dtype=np.int64)
    width = parts[0].values.shape[1] if parts else 1
    out = _Part(cat([q.stamp for q in parts], z), cat(codes, np.zeros(0, np.intp)), frames,
                cat([q.values for q in parts], np.zeros((0, width))),
                cat([q.log_time for q in parts], z), cat([q.chunk for q in parts], z),
                cat([q.record for q in parts], z))
    if len(out.log_time) > 1 and bool(np.any(np.diff(out.log_time) < 0)):
        order = np.lexsort((out.record, out.chunk, out.log_time))
        out = _Part(out.stamp[order], out.frame[order], frames, out.values[order],
                    out.log_time[order], out.chunk[order], out.record[order])
    return out
