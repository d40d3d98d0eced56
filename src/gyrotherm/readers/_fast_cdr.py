"""ROS 2 CDR ``sensor_msgs/msg/Imu`` and ``sensor_msgs/msg/Temperature`` decoded by
numpy, many messages at once (the fast path of ``_rosbag``).

Each message is ``00 01 00 00`` (CDR little endian, the encapsulation header) and
then, aligned relative to the byte after that header (ROS 2 Humble, every release)::

    Header:      int32 stamp.sec @0, uint32 stamp.nanosec @4,
                 string frame_id: uint32 n @8 (bytes with the NUL), n bytes @12
    Imu:         @a = align8(12 + n): float64 orientation[4] @a, covariance[9] @a+32,
                 angular_velocity[3] @a+104, covariance[9] @a+128,
                 linear_acceleration[3] @a+200, covariance[9] @a+224; a+296 bytes
    Temperature: @a: float64 temperature @a, variance @a+8; a+16 bytes

The messages of one connection usually share ``n``; the field offsets then are the
same per message and each field is one numpy gather (a view of the buffer with a
one-byte stride). Anything rosbags would decode differently or refuse — another
encapsulation, ``n`` out of bounds or without its NUL, a frame id ending in NUL bytes
or not UTF-8, a size other than rosbags accepts (the decoded end up to 3 bytes of
padding short of the message's) — raises :class:`Fallback`, and the reader lets
rosbags decode.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.readers._fast_common import Fallback, field_at

IntArray = NDArray[np.int64]
_IMU_SIZE, _TEMP_SIZE = 296, 16
_F8 = np.dtype("<f8")
_HEAD = np.dtype([("enc", "<u4"), ("sec", "<i4"), ("nsec", "<u4"), ("n", "<u4")])
_VEC = np.dtype([("v", "<f8", (3,)), ("cov0", "<f8")])
"""A Vector3 (@104 ω, @200 a) and the first element of the covariance after it."""


@dataclass
class Header:
    """Stamps (ns, int64) and frame ids (an index into ``frames`` per message)."""

    stamp_ns: IntArray
    frame: NDArray[np.intp]
    frames: list[str]
    body: IntArray  # offset of the aligned body (``@a``) of each message in the buffer


def _header(buf: NDArray[np.uint8], start: IntArray, size: IntArray, body_size: int
            ) -> Header:
    if len(start) == 0:
        return Header(np.zeros(0, np.int64), np.zeros(0, np.intp), [], np.zeros(0, np.int64))
    if np.any(size < 16):
        raise Fallback("a CDR message shorter than its header")
    head = field_at(buf, start, _HEAD)  # one gather for the fixed part
    if np.any(head["enc"] & 0xFFFF != 0x0100):  # bytes 00 01: little endian (options ignored)
        raise Fallback("a CDR message not little-endian CDR")
    d = start + 4
    sec = head["sec"].astype(np.int64)
    nsec = head["nsec"].astype(np.int64)
    n = head["n"].astype(np.int64)
    if np.any((n < 1) | (12 + n > size - 4)):
        raise Fallback("a CDR frame_id length out of bounds")
    if np.any(buf[d + 12 + n - 1] != 0):
        raise Fallback("a CDR frame_id without its terminating NUL")
    body = d + ((12 + n + 7) & ~7)
    end = body + body_size
    stop = start + size
    if np.any((end > stop) | (end + 3 < stop)):
        raise Fallback("a CDR message size other than its type's")
    frame, frames = _frames(buf, d + 12, n - 1)
    return Header(sec * 1_000_000_000 + nsec, frame, frames, body)


def _frames(buf: NDArray[np.uint8], at: IntArray, length: IntArray
            ) -> tuple[NDArray[np.intp], list[str]]:
    """Each message's frame id as an index into the distinct frame ids (first seen
    first)."""
    code = np.zeros(len(at), dtype=np.intp)
    names: list[str] = []
    one = len(length) and bool(np.all(length == length[0]))  # the usual: one frame id
    for n in [int(length[0])] if one else np.unique(length).tolist():
        sel = np.arange(len(at)) if one else np.flatnonzero(length == n)
        if n == 0:
            values: NDArray[Any] = np.zeros(len(sel), dtype="S1")
        else:
            if np.any(buf[at[sel] + n - 1] == 0):
                raise Fallback("a CDR frame_id ending in a NUL byte")
            values = field_at(buf, at[sel], np.dtype(f"S{n}"))
        first = values[0]
        if bool(np.all(values == first)):
            uniq, inverse = values[:1], np.zeros(len(sel), dtype=np.intp)
        else:
            uniq, inverse = np.unique(values, return_inverse=True)
        for k, raw in enumerate(uniq.tolist()):
            try:
                name = bytes(raw).decode() if n else ""
            except UnicodeDecodeError as exc:
                raise Fallback("a CDR frame_id not UTF-8") from exc
            if name not in names:
                names.append(name)
            code[sel[inverse == k]] = names.index(name)
    return code, names


@dataclass
class ImuColumns:
    """Decoded ``Imu`` messages: header, ω x y z and a x y z (rad/s, m/s²), and the
    first element of the two covariances (-1 marks the vector absent)."""

    header: Header
    values: NDArray[np.float64]  # (n, 6)
    rate_cov0: NDArray[np.float64]
    accel_cov0: NDArray[np.float64]


def decode_imu(buf: NDArray[np.uint8], start: IntArray, size: IntArray,
               out: NDArray[np.float64] | None = None) -> ImuColumns:
    """The ``Imu`` messages at ``start`` (``size`` bytes each) of ``buf`` (the six
    values written into ``out`` when given, shape (n, 6))."""
    h = _header(buf, start, size, _IMU_SIZE)
    values = np.empty((len(start), 6)) if out is None else out
    w = field_at(buf, h.body + 104, _VEC)  # a vector and its covariance's first element
    a = field_at(buf, h.body + 200, _VEC)
    values[:, :3] = w["v"]
    values[:, 3:] = a["v"]
    return ImuColumns(h, values, w["cov0"], a["cov0"])


def decode_temperature(buf: NDArray[np.uint8], start: IntArray, size: IntArray
                       ) -> tuple[Header, NDArray[np.float64]]:
    """The ``Temperature`` messages' headers and temperatures (°C)."""
    h = _header(buf, start, size, _TEMP_SIZE)
    temp: NDArray[np.float64] = field_at(buf, h.body, _F8)
    return h, temp
