"""Has an IMU drifted since its last calibration? The numbers of ``gyrotherm fleet``.

An IMU is its runs' ``(vehicle_id, device_id, sensor_id)`` (:mod:`._identity`). Its
previous calibration is the one in ``--previous DIR`` that :func:`match` picks: same
``device_id`` and, where both sides name them, the same ``sensor_id`` and
``vehicle_id`` (the rule of ``evaluate``), the most specific match first, then the
latest ``fit_time_utc``, then the file name.

Two numbers, both in °/s, both compared with one threshold (``--threshold-dps``):

* **shift**: how far the new fit's bias is from the previous calibration's where the
  IMU was: the RMS of (new − previous bias) over the new logs' rows at rest whose
  temperature lies in the range both calibrations were fitted over (each bias at the
  row's T and ΔT), the largest over the axes both have (None when the ranges do not
  overlap). Rows, not a grid of temperatures: between the temperatures a log held
  still, the steady-state bias (ΔT = 0) is the model's interpolation, which varies by
  a few hundredths of °/s from fit to fit of the same IMU.
* **residual**: what the previous calibration leaves in the new logs, held out (they
  were not part of its fit): per run and axis the mean of raw − previous bias over the
  rows at rest, the RMS of those means over the runs, the largest over the axes. A mean
  per run removes the white noise that no calibration can; what remains is the bias
  the previous calibration gets wrong (plus each run's switch-on offset). The same
  number for the new fit (``residual_new_dps``) shows that floor.

``drifted`` when either exceeds the threshold.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm._errors import GyrothermError
from gyrotherm.compensation import Calibration, RunFeatures

KEYS = ("vehicle_id", "device_id", "sensor_id")
DEFAULT_THRESHOLD_DPS = 0.05
"""°/s: 3 °/min of heading error; above a MEMS gyro's switch-on repeatability and bias
instability (≈ 0.01 °/s each in the simulator's default profile), well below the
thermal bias a calibration removes (tenths of °/s over a flight's range)."""

Key = tuple[str, str, str]


@dataclass(frozen=True)
class Previous:
    path: str
    calibration: Calibration

    @property
    def ids(self) -> dict[str, str]:
        return {k: str(self.calibration.provenance.get(k, "") or "") for k in KEYS}


def load_previous(directory: str | None) -> list[Previous]:
    """Every calibration ``*.json`` in ``directory`` (sorted by name; a file that is
    not one is left out with a note)."""
    if not directory:
        return []
    from gyrotherm.compensation import load_calibration

    d = Path(directory)
    if not d.is_dir():
        raise OSError(2, "no such directory (--previous)", str(d))
    out = []
    for path in sorted(d.glob("*.json")):
        try:
            out.append(Previous(str(path), load_calibration(path)))
        except GyrothermError as exc:
            print(f"note: --previous: left out: {exc}", file=sys.stderr)
    return out


def match(key: Key, previous: Sequence[Previous]) -> Previous | None:
    """The previous calibration of the IMU ``key`` (module docstring), or None."""
    ids = dict(zip(KEYS, key, strict=True))

    def rank(p: Previous) -> tuple[int, str, str] | None:
        mine = p.ids
        if mine["device_id"] != ids["device_id"]:
            return None
        agree = 0
        for k in ("vehicle_id", "sensor_id"):
            if mine[k] and ids[k]:
                if mine[k] != ids[k]:
                    return None
                agree += 1
        return agree, str(p.calibration.provenance.get("fit_time_utc", "")), p.path

    ranked = [(r, p) for p in previous if (r := rank(p)) is not None]
    return max(ranked, key=lambda rp: rp[0])[1] if ranked else None


def shift(new: Calibration, old: Calibration, feats: Sequence[RunFeatures]
          ) -> tuple[float | None, str, list[float] | None]:
    """(RMS of new − previous bias over the logs' rest rows in the common range °/s,
    largest over the axes; its axis; the common range °C)."""
    from gyrotherm.compensation import removed_bias

    lo = max(new.valid_range.t_min_c, old.valid_range.t_min_c)
    hi = min(new.valid_range.t_max_c, old.valid_range.t_max_c)
    if hi < lo:
        return None, "", None
    sums: dict[str, list[float]] = {}
    for f in feats:
        inside = f.rows((f.temperature_c >= lo) & (f.temperature_c <= hi))
        b_old = removed_bias(old, f).bias
        for axis, (b_new, _clamped) in removed_bias(new, f).bias.items():
            if axis in b_old:
                d = f.rows(b_new - b_old[axis][0])[inside]
                acc = sums.setdefault(axis, [0.0, 0.0])
                acc[0] += float(np.sum(d * d))
                acc[1] += d.size
    per_axis = {a: math.sqrt(s2 / n) for a, (s2, n) in sums.items() if n}
    if not per_axis:
        return None, "", [float(lo), float(hi)]
    axis = max(per_axis, key=lambda a: per_axis[a])
    return per_axis[axis], axis, [float(lo), float(hi)]


def residual(cal: Calibration, feats: Sequence[RunFeatures]) -> tuple[float | None, str]:
    """(RMS over runs of the per-run mean of raw − ``cal``'s bias at rest, largest over
    axes °/s; its axis); None when no run has a row at rest on a common axis."""
    from gyrotherm.compensation import removed_bias

    means: dict[str, list[float]] = {}
    for f in feats:
        for axis, (bias, _clamped) in removed_bias(cal, f).bias.items():
            e = f.rows(f.rates_dps[axis] - bias)
            if e.size:
                means.setdefault(axis, []).append(float(np.mean(e)))
    if not means:
        return None, ""
    per_axis = {a: math.sqrt(math.fsum(m * m for m in v) / len(v)) for a, v in means.items()}
    axis = max(per_axis, key=lambda a: per_axis[a])
    return per_axis[axis], axis


def drift(new: Calibration, feats: Sequence[RunFeatures], old: Previous | None, *,
          threshold_dps: float) -> dict[str, Any]:
    """The drift entry of one fitted IMU (module docstring): status ``new`` (no previous
    calibration), ``drifted`` or ``ok``, and the numbers."""
    own, _ = residual(new, feats)
    out: dict[str, Any] = {"previous": None, "shift_dps": None, "shift_axis": None,
                           "common_range_c": None, "residual_dps": None,
                           "residual_axis": None, "residual_new_dps": _r(own)}
    if old is None:
        return {**out, "status": "new"}
    s, s_axis, common = shift(new, old.calibration, feats)
    r, r_axis = residual(old.calibration, feats)
    flagged = any(v is not None and v > threshold_dps for v in (s, r))
    return {**out, "status": "drifted" if flagged else "ok", "previous": old.path,
            "previous_fit_time_utc": old.calibration.provenance.get("fit_time_utc"),
            # the previous calibration is scored on these logs' T/ΔT, estimated with the
            # new calibration's estimator: say when its own was another
            "previous_estimator_differs": old.calibration.estimator != new.estimator,
            "shift_dps": _r(s), "shift_axis": s_axis or None,
            "common_range_c": common, "residual_dps": _r(r), "residual_axis": r_axis or None}


def _r(v: float | None) -> float | None:
    return None if v is None else round(v, 6)


def identity(meta: Mapping[str, str]) -> Key:
    v, d, s = (str(meta.get(k, "") or "") for k in KEYS)
    return v, d, s


__all__ = ["DEFAULT_THRESHOLD_DPS", "KEYS", "Key", "Previous", "drift", "identity",
           "load_previous", "match", "residual", "shift"]
