"""The consistency message (kind 5): do two IMUs' corrected rates agree?

Published by the daemon with several IMUs on ``gyrotherm/<vehicle>/consistency/<a>/<b>``
once per window (docs/wire-format.md, "Several IMUs: frame ids and consistency";
:mod:`gyrotherm.daemon._consistency` computes it). One msgpack array::

    0 kind (5), 1 version (1), 2 seq, 3 receive_time_s (window end, wall clock),
    4 window_s, 5 sensor_a, 6 sensor_b, 7 samples (pairs of time-aligned rates),
    8-10 mean_dps x y z (mean of a − b), 11-13 noise_dps x y z (standard error of
    that mean from the differences' own scatter), 14-16 limit_dps x y z
    (tolerance_dps + k_sigma · noise_dps), 17 flags

``flags``: bit 0/1/2 axis x/y/z inconsistent (``|mean| > limit``), bit 3 no data
(fewer than ``min_samples`` aligned pairs: one of the two is silent). 0: consistent.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any

import msgpack

from gyrotherm._errors import DecodeError
from gyrotherm.codecs._wire import SCHEMA_VERSION, Payload, Vec3

CONSISTENCY_KIND = 5


class ConsistencyFlags(enum.IntFlag):
    NONE = 0
    X = 1
    Y = 2
    Z = 4
    NO_DATA = 8


AXIS_FLAGS = (ConsistencyFlags.X, ConsistencyFlags.Y, ConsistencyFlags.Z)


@dataclass(frozen=True)
class ConsistencyMessage:
    """One pair's verdict over one window (module docstring for the fields)."""

    seq: int
    receive_time_s: float
    window_s: float
    sensor_a: str
    sensor_b: str
    samples: int
    mean_dps: Vec3
    noise_dps: Vec3
    limit_dps: Vec3
    flags: ConsistencyFlags

    @property
    def consistent(self) -> bool:
        return self.flags == ConsistencyFlags.NONE

    @property
    def axes(self) -> str:
        """The inconsistent axes, e.g. ``"x"`` or ``"xz"`` (empty when none)."""
        return "".join(a for a, f in zip("xyz", AXIS_FLAGS, strict=True) if self.flags & f)


def encode_consistency(m: ConsistencyMessage) -> bytes:
    out: bytes = msgpack.packb([CONSISTENCY_KIND, SCHEMA_VERSION, m.seq, m.receive_time_s,
                                m.window_s, m.sensor_a, m.sensor_b, m.samples, *m.mean_dps,
                                *m.noise_dps, *m.limit_dps, int(m.flags)])
    return out


def _vec(a: list[Any], i: int) -> Vec3:
    return (float(a[i]), float(a[i + 1]), float(a[i + 2]))


def decode_consistency(payload: Payload) -> ConsistencyMessage:
    """Decode a consistency payload; DecodeError says what is wrong."""
    try:
        a = msgpack.unpackb(payload, raw=False)
    except Exception as exc:
        raise DecodeError(f"consistency payload: not valid msgpack: {exc}") from exc
    if type(a) is not list or len(a) < 18 or a[0] != CONSISTENCY_KIND:
        raise DecodeError(f"consistency payload: expected an array of 18 elements of kind "
                          f"{CONSISTENCY_KIND}, got {a!r:.80}")
    if a[1] != SCHEMA_VERSION:
        raise DecodeError(f"consistency payload: version {a[1]!r} is not {SCHEMA_VERSION}")
    try:
        nums = [float(v) for v in a[8:17]] + [float(a[3]), float(a[4])]
        ok = (all(type(a[i]) is int and a[i] >= 0 for i in (2, 7, 17))
              and all(type(a[i]) is str for i in (5, 6)) and not any(map(math.isinf, nums)))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise DecodeError(f"consistency payload: malformed fields {a!r:.200}")
    return ConsistencyMessage(a[2], float(a[3]), float(a[4]), a[5], a[6], a[7], _vec(a, 8),
                              _vec(a, 11), _vec(a, 14), ConsistencyFlags(a[17] & 0xF))
