"""The IMU and temperature rows of an indexed ``.mcap`` file, decoded by numpy: the
fast path of ``_rosbag`` (the same rows, in the same order, as its loop over rosbags'
messages). The container is read by :mod:`._fast_mcap`, the CDR by :mod:`._fast_cdr`;
the chunks' messages are decoded a few MiB of chunks at a time (fewer numpy calls than
per chunk, still in cache).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_cdr import decode_imu, decode_temperature
from gyrotherm.readers._fast_common import Fallback
from gyrotherm.readers._fast_mcap import (
    Indexed,
    Messages,
    Plan,
    Source,
    checked,
    load,
    plan,
    summary,
)

IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
_GROUP = 1 << 22  # bytes of chunks decoded together (in cache, few numpy calls)
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
    plans = [q for q in (plan(src, c, sorted(ids)) for c in s.chunks) if q is not None]
    out = {cid: _Out(sum(len(q.offs.get(cid, ())) for q in plans), msgtype)
           for cid, (_, msgtype) in ids.items()}
    group: list[Plan] = []
    held = 0
    for q in [*plans, None]:
        if group and (q is None or held + q.chunk.uncompressed_size > _GROUP):
            by_channel: dict[int, list[Indexed]] = {}
            for cid, m in load(src, group):
                by_channel.setdefault(cid, []).append(m)
            for cid, ms in by_channel.items():
                out[cid].add(checked(cid, ms))
            group, held = [], 0
        if q is not None:
            group.append(q)
            held += q.chunk.uncompressed_size
    imu: dict[tuple[str, str], tuple[IntArray, NDArray[np.float64]]] = {}
    temps: dict[str, NDArray[np.float64]] = {}
    missing: dict[str, int] = {}
    for cid, (topic, msgtype) in ids.items():
        o = out.pop(cid).done()
        zero = o.stamp == 0
        if msgtype == TEMPERATURE_TYPE:
            ns = np.where(zero, o.log_time, o.stamp)
            temps[topic] = np.column_stack([ns.astype(np.float64), o.values[:, 0]])
            continue
        if zero.any():
            missing[topic] = int(np.count_nonzero(zero))
        ns = np.where(zero, o.log_time, o.stamp) if missing.get(topic) else o.stamp
        for k, frame in enumerate(o.frames):
            if len(o.frames) == 1:
                imu[(topic, frame)] = (ns, o.values)
                continue
            sel = o.frame == k
            imu[(topic, frame)] = (ns[sel], o.values[sel])
    return imu, temps, missing


class _Out:
    """One channel's decoded messages, filled a group of chunks at a time into arrays
    of the size its message indexes announce (no joining at the end)."""

    def __init__(self, n: int, msgtype: str) -> None:
        self.msgtype = msgtype
        self.stamp = np.empty(n, dtype=np.int64)
        self.log_time = np.empty(n, dtype=np.int64)
        self.frame = np.empty(n, dtype=np.intp)
        self.values = np.empty((n, 1 if msgtype == TEMPERATURE_TYPE else 6))
        self.frames: list[str] = []
        self.n = 0

    def add(self, m: Messages) -> None:
        k = len(m.start)
        at = slice(self.n, self.n + k)
        if self.msgtype == TEMPERATURE_TYPE:
            h, temp = decode_temperature(m.buf, m.start, m.size)
            self.values[at, 0] = temp
        else:
            cols = decode_imu(m.buf, m.start, m.size, out=self.values[at])
            h = cols.header
            self.values[at][cols.rate_cov0 == -1.0, :3] = np.nan
            self.values[at][cols.accel_cov0 == -1.0, 3:] = np.nan
        self.stamp[at] = h.stamp_ns
        self.log_time[at] = m.log_time
        for f in h.frames:
            if f not in self.frames:
                self.frames.append(f)
        if h.frames == self.frames[:1]:
            self.frame[at] = 0
        else:
            remap = np.array([self.frames.index(f) for f in h.frames] or [0], dtype=np.intp)
            self.frame[at] = remap[h.frame]
        self.n += k

    def done(self) -> _Out:
        """Trimmed to what was decoded (messages outside their chunk's time range are
        left out), in rosbags' order: by log time, ties in file order (chunk, record)."""
        n = self.n
        self.stamp, self.log_time = self.stamp[:n], self.log_time[:n]
        self.frame, self.values = self.frame[:n], self.values[:n]
        if n > 1 and bool(np.any(self.log_time[1:] < self.log_time[:-1])):
            order = np.argsort(self.log_time, kind="stable")
            self.stamp, self.log_time = self.stamp[order], self.log_time[order]
            self.frame, self.values = self.frame[order], self.values[order]
        return self
