"""A ``candump -l`` log of the gyro's CAN frames as a :class:`~gyrotherm.codecs.Run`.

:func:`run_from_candump` decodes every frame with a
:class:`~gyrotherm.codecs.FrameDecoder` (DBC + signal map) and builds one run
row per rate sample:

* ``rate_<axis>_dps``: the rate sample's axes. An axis that is exactly 0 °/s in
  every sample carries no measurement (senders fill absent axes with 0, as
  :func:`gyrotherm.sim.frames_from_run` does) and is dropped, unless every
  axis is; the dropped axes are listed in ``metadata["axes_dropped_all_zero"]``.
* ``temperature_c``: the latest temperature sample at or before the rate
  sample's timestamp (the reading the device reported last). Rate samples
  before the first temperature sample are dropped and counted
  (``rows_before_first_temperature``).
* ``time_s``: time since power-on. Timestamps below :data:`POWER_ON_LIMIT_S`
  (10⁶ s, 11.6 days) are taken as the device's own time since power-on and
  kept (``time_origin: log``: a warm-up transient stays where it happened);
  larger ones are wall-clock times, and the timestamp of the log's first
  frame of a mapped message (rate or temperature id, decoded or not) is
  subtracted (``time_origin: first frame``, ``time_origin_s`` = that
  timestamp). The first frame on the bus is the closest the log comes to
  the power-on time, so time since power-on may be underestimated by however
  long the device ran before the log started.

Nothing is dropped silently: per-reason counts go into ``run.metadata``.
``frames_rejected_<reason>`` counts the decoder's rejections
(:class:`~gyrotherm.codecs.RejectReason`: ``unknown_id`` frames of other
devices, ``wrong_length``, ``crc_mismatch``, ``decode_error`` — error and
remote frames too —, ``out_of_range``; ``counter_jump`` stays 0, the decoder
runs with its default policy of delivering a sample after a jump) and two of
this reader's own: ``duplicate_time`` (a sample
whose timestamp equals the previous kept sample of the same message: the
first is kept) and ``time_backwards`` (an earlier timestamp than that).
``counter_jumps`` counts counter discontinuities of delivered samples (the
decoder delivers them: their data passed the CRC), ``temperature_status_nonzero``
the temperature samples whose status byte flags a device fault (kept).

Errors (:class:`gyrotherm.RunFileError`, naming the file): a line that is not
``candump -l`` (file and line number), a log without any valid rate frame or
temperature frame, or one whose rate frames all precede the first temperature.
"""

from __future__ import annotations

import hashlib
import os
import re
from array import array
from collections import Counter
from pathlib import Path

import numpy as np

from gyrotherm._errors import DecodeError, RunFileError
from gyrotherm.codecs._can import FrameDecoder, RateSample, Rejection, RejectReason
from gyrotherm.codecs._candump import parse_candump_line
from gyrotherm.codecs._canmap import DEFAULT_DBC_PATH, EXTENDED_KEY, SignalMap
from gyrotherm.codecs._runfile import AXES, Run

POWER_ON_LIMIT_S = 1e6
"""Timestamps below this (s) are read as time since power-on; above, as wall-clock time."""
DUPLICATE_TIME = "duplicate_time"
TIME_BACKWARDS = "time_backwards"
_HEAD = re.compile(rb"^\(\d+\.\d+\)\s+\S+\s+[0-9A-Fa-f]+#")
_SNIFF_BYTES = 65536
#: A classic data frame, the common case, parsed without building a ``can.Message``
#: (anything else, and every malformed line, goes through ``parse_candump_line``).
_CLASSIC = re.compile(
    r"^\((\d+\.\d+)\)\s+\S+\s+([0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})#((?:[0-9A-Fa-f]{2}){0,8})"
    r"(?:\s+[RTrt])?$")
_STANDARD_MAX, _EXTENDED_MAX = 0x7FF, 0x1FFFFFFF


def is_candump_log(path: str | os.PathLike[str]) -> bool:
    """Whether the first non-empty line of ``path`` is ``(<seconds>) <iface> <id>#<data>``.

    Decided by content, not by the file name; False when the file cannot be read.
    """
    try:
        with Path(path).open("rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError:
        return False
    for line in head.splitlines():
        if line.strip():
            return _HEAD.match(line.strip()) is not None
    return False


class _Stream:
    """Samples of one message with strictly increasing timestamps (flat float arrays)."""

    def __init__(self, width: int) -> None:
        self.width = width
        self.time_s = array("d")
        self.values = array("d")

    def add(self, time_s: float, values: tuple[float, ...], rejected: Counter[str]) -> bool:
        if self.time_s and time_s <= self.time_s[-1]:
            rejected[DUPLICATE_TIME if time_s == self.time_s[-1] else TIME_BACKWARDS] += 1
            return False
        self.time_s.append(time_s)
        self.values.extend(values)
        return True

    def matrix(self) -> np.ndarray:
        return np.frombuffer(self.values, dtype=np.float64).reshape(-1, self.width)


def run_from_candump(
    path: str | os.PathLike[str],
    *,
    dbc_path: str | os.PathLike[str] = DEFAULT_DBC_PATH,
    signal_map: SignalMap | None = None,
    name: str | None = None,
) -> Run:
    """The run recorded in the ``candump -l`` log ``path`` (see the module docstring).

    ``name`` defaults to the file's stem. ``run.sha256`` is that of the log file.
    """
    p = Path(path)
    decoder = FrameDecoder(dbc_path, signal_map)
    layout = decoder.layout
    mapped = {layout.rate.key, layout.temperature.key}
    rates, temps = _Stream(3), _Stream(1)
    rejected: Counter[str] = Counter()
    status_nonzero = 0
    first_mapped: float | None = None
    digest = hashlib.sha256()
    try:
        fh = p.open("rb")
    except OSError as exc:
        raise RunFileError(f"{p}: cannot open candump log: {exc}") from exc
    with fh:
        for line_no, raw in enumerate(fh, start=1):
            digest.update(raw)
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise RunFileError(f"{p}:{line_no}: not a text candump log: {exc}") from exc
            if not text.strip():
                continue
            m = _CLASSIC.match(text.strip())
            ident = int(m[2], 16) if m else -1
            extended = m is not None and len(m[2]) == 8
            if ident >= 0 and ident <= (_EXTENDED_MAX if extended else _STANDARD_MAX):
                assert m is not None
                stamp = float(m[1])
                key = ident + (EXTENDED_KEY if extended else 0)
                res = decoder.decode_raw(ident, bytes.fromhex(m[3]), stamp,
                                         is_extended_id=extended)
            else:
                try:
                    msg = parse_candump_line(text, source=str(p), line_no=line_no)
                except DecodeError as exc:
                    raise RunFileError(str(exc)) from exc
                stamp = float(msg.timestamp)
                key = -1 if msg.is_error_frame else (
                    msg.arbitration_id + (EXTENDED_KEY if msg.is_extended_id else 0))
                res = decoder.decode(msg)
            if first_mapped is None and key in mapped:
                first_mapped = stamp
            if isinstance(res, Rejection):
                rejected[res.reason.value] += 1
            elif isinstance(res, RateSample):
                rates.add(res.time_s, (res.rate_x_dps, res.rate_y_dps, res.rate_z_dps), rejected)
            elif temps.add(res.time_s, (res.temperature_c,), rejected) and res.status:
                status_nonzero += 1
    stats = decoder.stats()
    summary = _summary(rejected)
    if not rates.time_s:
        raise RunFileError(
            f"{p}: candump log has no valid rate frame (message {layout.rate.name!r}, "
            f"id 0x{layout.rate.frame_id:X}) among {stats.frames} frames ({summary})")
    if not temps.time_s:
        raise RunFileError(
            f"{p}: candump log has no valid temperature frame (message "
            f"{layout.temperature.name!r}, id 0x{layout.temperature.frame_id:X}) among "
            f"{stats.frames} frames ({summary})")
    rate_t = np.frombuffer(rates.time_s, dtype=np.float64)
    temp_t = np.frombuffer(temps.time_s, dtype=np.float64)
    latest = np.searchsorted(temp_t, rate_t, side="right") - 1
    keep = latest >= 0
    if not keep.any():
        raise RunFileError(
            f"{p}: candump log: all {len(rate_t)} rate samples precede the first temperature "
            f"sample (at {temp_t[0]:.6f} s)")
    assert first_mapped is not None
    metadata = {"source_format": "candump", "dbc": Path(decoder.dbc_path).name,
                "frames": str(stats.frames)}
    if first_mapped < POWER_ON_LIMIT_S:
        origin = 0.0
        metadata["time_origin"] = "log"
    else:
        origin = first_mapped
        metadata["time_origin"] = "first frame"
        metadata["time_origin_s"] = f"{first_mapped:.6f}"
    values = rates.matrix()[keep]
    axes = {a: values[:, i] for i, a in enumerate(AXES)}
    dead = [a for a in AXES if not np.any(axes[a])]
    if len(dead) < len(AXES):
        for a in dead:
            del axes[a]
        if dead:
            metadata["axes_dropped_all_zero"] = ",".join(dead)
    for reason in (*(r.value for r in RejectReason), DUPLICATE_TIME, TIME_BACKWARDS):
        metadata[f"frames_rejected_{reason}"] = str(rejected[reason])
    metadata["counter_jumps"] = str(stats.events[RejectReason.COUNTER_JUMP]
                                    - rejected[RejectReason.COUNTER_JUMP.value])
    metadata["rows_before_first_temperature"] = str(int(np.sum(~keep)))
    metadata["temperature_samples"] = str(len(temp_t))
    metadata["temperature_status_nonzero"] = str(status_nonzero)
    return Run(
        name=name if name is not None else p.stem,
        time_s=rate_t[keep] - origin,
        temperature_c=temps.matrix()[latest[keep], 0],
        rates_dps=axes,
        metadata=metadata,
        source=str(p),
        sha256=digest.hexdigest(),
    )


def _summary(rejected: Counter[str]) -> str:
    parts = [f"{reason}: {n}" for reason, n in sorted(rejected.items()) if n]
    return "rejected " + ", ".join(parts) if parts else "none rejected"
