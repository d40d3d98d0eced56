"""What ``gyrotherm fleet`` prints without ``--json``: a line per IMU's calibration,
then the drift table (:mod:`._drift`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

_COLUMNS = ("vehicle", "device", "sensor", "runs", "status", "shift °/s", "over °C",
            "residual °/s", "new fit °/s", "previous")


def _num(v: float | None) -> str:
    return "-" if v is None else f"{v:.4f}"


def _who(imu: dict[str, Any]) -> str:
    sensor = f" (sensor {imu['sensor_id']})" if imu["sensor_id"] else ""
    return f"vehicle {imu['vehicle_id'] or '?'}, device {imu['device_id'] or '?'}{sensor}"


def calibration_line(imu: dict[str, Any]) -> str:
    """One IMU's calibration: runs, range, steady-state bias at the range's ends."""
    if imu["calibration"] is None and imu["status"] == "not fitted":
        return f"{_who(imu)}: {len(imu['runs'])} runs, not fitted: {imu['reason']}"
    lo, hi = imu["valid_range_c"]
    ends = "; ".join(f"{axis} {b[0]:+.4f} → {b[1]:+.4f}"
                     for axis, b in imu["steady_bias_dps"].items())
    where = f"; wrote {imu['calibration']}" if imu["calibration"] else ""
    return (f"{_who(imu)}: {len(imu['runs'])} runs, {imu['model']}, {lo:.1f}…{hi:.1f} °C, "
            f"steady bias °/s {ends}{where}")


def _row(imu: dict[str, Any]) -> tuple[str, ...]:
    common = imu.get("common_range_c")
    over = f"{common[0]:.1f}…{common[1]:.1f}" if common else "-"
    return (imu["vehicle_id"] or "?", imu["device_id"] or "?", imu["sensor_id"] or "-",
            str(len(imu["runs"])), imu["status"], _num(imu.get("shift_dps")), over,
            _num(imu.get("residual_dps")), _num(imu.get("residual_new_dps")),
            imu.get("previous") or "-")


def drift_table(imus: Sequence[dict[str, Any]], *, threshold_dps: float) -> str:
    rows = [_COLUMNS, *(_row(i) for i in imus)]
    widths = [max(len(r[c]) for r in rows) for c in range(len(_COLUMNS))]
    lines = ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip()
             for r in rows]
    lines.insert(1, "-" * len(lines[0]))
    drifted = [i for i in imus if i["status"] == "drifted"]
    lines.insert(0, f"Drift since the last calibration (threshold {threshold_dps:g} °/s; "
                 "shift: new − previous bias on these logs' rest rows in the common range; "
                 "residual: the previous calibration on these logs, held out):")
    lines.append(f"{len(drifted)} of {len(imus)} IMUs drifted"
                 + (": " + ", ".join(_who(i) for i in drifted) if drifted else ""))
    return "\n".join(lines)


def print_fleet(imus: Sequence[dict[str, Any]], *, threshold_dps: float,
                previous: bool) -> None:
    for imu in imus:
        print(calibration_line(imu))
    print()
    if not previous:
        print("no --previous directory: every IMU is new (nothing to compare with)")
    print(drift_table(imus, threshold_dps=threshold_dps))
