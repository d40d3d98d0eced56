"""Helpers shared by the binary-log readers (ULog, DataFlash, rosbag2/MCAP).

:func:`make_run` turns arrays in the source's own units into a :class:`Run` in
the project's (s, °C, °/s; accelerometer m/s² in ``Run.extra``), with the
conventions every reader follows:

* rows whose time, temperature or rate is not finite are dropped;
* rows are sorted by time and repeated time stamps dropped (first kept);
* what was dropped or reordered is counted in the metadata
  (``rows_nonfinite_dropped``, ``rows_duplicate_time_dropped``,
  ``rows_reordered``), so nothing disappears silently;
* no row left → :class:`RunFileError` naming the file, the message/topic and
  what is missing.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run

FloatArray = NDArray[np.float64]

DEG_PER_RAD = 180.0 / math.pi
"""rad/s → °/s."""
S_PER_US = 1e-6
S_PER_NS = 1e-9
ACCEL_KEYS = {"x": "accel_x_mps2", "y": "accel_y_mps2", "z": "accel_z_mps2"}
"""``Run.extra`` keys of the accelerometer axes (m/s²)."""
FALLBACK_KEY = "fast_path_fallback"
"""Metadata key: why a binary log was decoded by its library (pymavlink, pyulog,
rosbags) instead of the readers' numpy fast path; absent when the fast path read it."""
ARMED_KEY = "armed"
"""``Run.extra`` key of the vehicle's arming state at each row: 1 armed, 0 disarmed."""


def sha256_of(path: str | os.PathLike[str]) -> str:
    """sha256 of a file, or of a directory's files (each file's relative name and
    content hash, in name order)."""
    p = Path(path)
    if p.is_file():
        return _file_sha256(p)
    h = hashlib.sha256()
    for f in sorted(x for x in p.rglob("*") if x.is_file()):
        h.update(f.relative_to(p).as_posix().encode("utf-8") + b"\0")
        h.update(_file_sha256(f).encode("ascii") + b"\n")
    return h.hexdigest()


def _file_sha256(p: Path) -> str:
    h = hashlib.sha256()
    with p.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def hold_previous(t_src: FloatArray, v_src: FloatArray, t_dst: FloatArray) -> FloatArray:
    """``v_src`` at each ``t_dst`` by nearest earlier (or equal) sample (hold);
    NaN where ``t_dst`` precedes every ``t_src``. ``t_src`` must be sorted."""
    idx = np.searchsorted(t_src, t_dst, side="right") - 1
    out = np.full(len(t_dst), np.nan)
    ok = idx >= 0
    out[ok] = v_src[idx[ok]]
    return out


def state_at(t_src: FloatArray, v_src: FloatArray, t_dst: FloatArray, before: float
             ) -> FloatArray:
    """A logged state (``v_src`` from ``t_src`` on, sorted) at each ``t_dst``: the latest
    at or before it; ``before`` for rows ahead of the first."""
    out = hold_previous(t_src, v_src, t_dst)
    out[np.isnan(out)] = before
    return out


def interpolate(t_src: FloatArray, v_src: FloatArray, t_dst: FloatArray) -> FloatArray:
    """``v_src`` linearly interpolated at ``t_dst`` (``t_src`` sorted). Up to one
    median sample period beyond either end the end value is held; further out NaN."""
    if len(t_src) == 0:
        return np.full(len(t_dst), np.nan)
    out: FloatArray = np.interp(t_dst, t_src, v_src)
    gap = float(np.median(np.diff(t_src))) if len(t_src) > 1 else 0.0
    out[(t_dst < t_src[0] - gap) | (t_dst > t_src[-1] + gap)] = np.nan
    return out


def sort_unique(t: FloatArray) -> tuple[NDArray[np.intp], int, int]:
    """Row order that sorts ``t`` (stable) with repeated values dropped: the indices,
    the number of rows out of order, the number dropped as repeats."""
    order = np.argsort(t, kind="stable")
    reordered = int(np.count_nonzero(np.diff(t) < 0)) if len(t) > 1 else 0
    ts = t[order]
    keep = np.ones(len(ts), dtype=bool)
    keep[1:] = np.diff(ts) > 0
    return order[keep], reordered, int(np.count_nonzero(~keep))


def make_run(
    *,
    path: Path,
    device: str,
    where: str,
    time_s: FloatArray,
    temperature_c: FloatArray,
    rates: Mapping[str, FloatArray],
    rate_to_dps: float,
    accel_mps2: Mapping[str, FloatArray] | None = None,
    armed: FloatArray | None = None,
    metadata: Mapping[str, str],
    sha256: str,
) -> Run:
    """A :class:`Run` named ``<file stem>:<device>`` from arrays in the source's
    units (time already in s, temperature in °C, rates × ``rate_to_dps`` → °/s).

    ``where`` names the message or topic in errors. Accelerometer values may be NaN
    (no sample near): the accelerometer is kept only when every remaining row has
    one, else left out with the count in metadata ``accel_rows_missing``. ``armed``
    (1/0 per row, from the log's arming state) goes to ``Run.extra["armed"]``.
    """
    t = np.asarray(time_s, dtype=np.float64)
    temp = np.asarray(temperature_c, dtype=np.float64)
    r = {a: np.asarray(v, dtype=np.float64) * rate_to_dps for a, v in rates.items()}
    finite = np.isfinite(t) & np.isfinite(temp)
    for v in r.values():
        finite &= np.isfinite(v)
    if not finite.any():
        missing = "temperature" if not np.isfinite(temp).any() else "finite samples"
        raise RunFileError(f"{path}: {where}: no {missing} in {len(t)} sample(s)")
    nonfinite = int(np.count_nonzero(~finite))
    if finite.all() and (len(t) < 2 or bool(np.all(np.diff(t) > 0))):
        sel: slice | NDArray[np.intp] = slice(None)  # the usual log: no argsort, no gather
        reordered = dupes = 0
    else:
        rows, reordered, dupes = sort_unique(t[finite])
        sel = np.flatnonzero(finite)[rows]
    extra: dict[str, FloatArray] = {}
    accel_missing = 0
    for a, v in (accel_mps2 or {}).items():
        acc = np.asarray(v, dtype=np.float64)[sel]
        accel_missing = max(accel_missing, int(np.count_nonzero(~np.isfinite(acc))))
        extra[ACCEL_KEYS[a]] = acc
    if accel_missing:  # keep the accelerometer only when every row has it
        extra = {}
    if armed is not None:
        extra[ARMED_KEY] = np.asarray(armed, dtype=np.float64)[sel]
    meta = {
        **metadata,
        **({"accel_rows_missing": str(accel_missing)} if accel_missing else {}),
        "rows_nonfinite_dropped": str(nonfinite),
        "rows_reordered": str(reordered),
        "rows_duplicate_time_dropped": str(dupes),
    }
    return Run(
        name=f"{path.stem}:{device}",
        time_s=t[sel],
        temperature_c=temp[sel],
        rates_dps={a: v[sel] for a, v in r.items()},
        metadata=meta,
        source=str(path),
        sha256=sha256,
        extra=extra,
    )


def each_instance(path: Path, attempts: Sequence[tuple[str, Callable[[], Run]]]) -> list[Run]:
    """The runs of a log's IMU instances (``(label, build)`` each): an instance whose
    build raises :class:`RunFileError` (NaN temperature throughout, fields missing) is
    skipped, the others kept with metadata ``instances_skipped`` saying which and why.
    Only when every instance fails is the log refused (naming each)."""
    runs: list[Run] = []
    skipped: list[str] = []
    for label, build in attempts:
        try:
            runs.append(build())
        except RunFileError as exc:
            reason = str(exc).removeprefix(f"{path}: ")
            skipped.append(reason if reason.startswith(label) else f"{label}: {reason}")
    if not runs and skipped:
        if len(skipped) == 1:
            raise RunFileError(f"{path}: {skipped[0]}")
        raise RunFileError(f"{path}: no usable IMU instance: " + "; ".join(skipped))
    if skipped:
        note = "; ".join(skipped)
        runs = [replace(r, metadata={**r.metadata, "instances_skipped": note}) for r in runs]
    return runs
