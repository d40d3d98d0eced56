"""The IMU and temperature rows of an indexed ``.mcap`` file, decoded by numpy: the
fast path of ``_rosbag`` (the same rows, in the same order, as its loop over rosbags'
messages). The container is read by :mod:`._fast_mcap`, the CDR by :mod:`._fast_cdr`;
messages of uncompressed chunks are decoded a few MiB of the file at a time (fewer
numpy calls than per chunk, still in cache), compressed chunks one at a time.
"""

from __future__ import annotations

import contextlib
import mmap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_cdr import decode_imu, decode_temperature
from gyrotherm.readers._fast_common import Fallback
from gyrotherm.readers._fast_mcap import Indexed, Messages, checked, chunk_messages, summary

IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
_GROUP = 1 << 23  # bytes of uncompressed chunks decoded together (in cache, few calls)
IntArray = NDArray[np.int64]


def gather(path: Path, imu_topics: list[str], temp_topics: list[str]
           ) -> tuple[dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]],
                      dict[str, NDArray[np.float64]], dict[str, int]]:
    """What ``_rosbag`` gathers with rosbags, decoded by numpy: IMU rows per (topic,
    frame_id) (stamps ns, (n, 6) ω and a, NaN where a covariance marks them absent),
    temperature rows per topic ((n, 2): stamp ns as float, °C), and per IMU topic the
    count of zero stamps (replaced by the log time)."""
    with path.open("rb") as fh:
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            return _gather(memoryview(mm), imu_topics, temp_topics)
        finally:
            with contextlib.suppress(BufferError):  # numpy views left to the collector
                mm.close()


def _gather(data: memoryview, imu_topics: list[str], temp_topics: list[str]
            ) -> tuple[dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]],
                       dict[str, NDArray[np.float64]], dict[str, int]]:
    s = summary(data)
    want = {IMU_TYPE: imu_topics, TEMPERATURE_TYPE: temp_topics}
    ids: dict[int, tuple[str, str]] = {}
    for msgtype, topics in want.items():
        for topic in topics:
            chans = [c for c in s.channels.values() if c.topic == topic]
            if len(chans) != 1 or chans[0].schema != msgtype or chans[0].encoding != "cdr":
                raise Fallback(f"topic {topic!r}: not one CDR {msgtype} channel")
            ids[chans[0].id] = (topic, msgtype)
    filebuf = np.frombuffer(data, dtype=np.uint8)
    parts: dict[int, list[_Part]] = {cid: [] for cid in ids}
    pending: dict[int, list[Indexed]] = {cid: [] for cid in ids}
    for chunk in s.chunks:
        for cid, m in chunk_messages(data, filebuf, chunk, sorted(ids)):
            group = pending[cid]
            if group and (m.buf is not filebuf or group[-1].buf is not filebuf
                          or m.hi - group[0].lo > _GROUP):
                parts[cid].append(_decode(checked(cid, group), ids[cid][1]))
                group.clear()
            group.append(m)
    for cid, group in pending.items():
        if group:
            parts[cid].append(_decode(checked(cid, group), ids[cid][1]))
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
