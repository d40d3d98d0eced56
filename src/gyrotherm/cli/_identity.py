"""Which physical IMU a run is, and which runs a calibration is for.

A run's identity is its metadata (set by the readers): ``device_id`` (the log's name
for the IMU: PX4's ``device_id``, ``IMU[<n>]`` for ArduPilot, a CSV's device column),
``sensor_id`` (the driver's device id: PX4's ``device_id``, ArduPilot's
``INS_GYR<n>_ID``) and ``vehicle_id`` (PX4 ``sys_uuid``, the ArduPilot board's unique
id). Empty means the log does not say.

* **fit** never pools one device name across vehicles by accident: a device whose runs
  name two or more vehicles is refused (``--pool-vehicles`` to pool them on purpose),
  naming the vehicles and a log of each. The calibration records ``vehicle_id`` and
  ``sensor_id`` when its runs agree on one.
* **evaluate, diagnose --calibration's scoring and export** use only the runs of the
  calibration's IMU: the same ``device_id`` and, where both sides know them, the same
  ``sensor_id`` and ``vehicle_id``. Runs that name no device are used (a plain CSV);
  others are left out with one note; none left is a refusal naming what was found.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.codecs import Run

KEYS = ("device_id", "sensor_id", "vehicle_id")


def _id(meta: Mapping[str, Any], key: str) -> str:
    return str(meta.get(key, "") or "")


def check_vehicles(runs: Sequence[Run], *, pool: bool) -> None:
    """ConfigError when one device name spans several vehicles (module docstring)."""
    seen: dict[str, dict[str, str]] = {}
    for r in runs:
        v = _id(r.metadata, "vehicle_id")
        if v:
            seen.setdefault(_id(r.metadata, "device_id"), {}).setdefault(v, r.source)
    for device, vehicles in seen.items():
        if len(vehicles) > 1 and not pool:
            listed = "; ".join(f"{v} ({src})" for v, src in vehicles.items())
            raise ConfigError(
                f"device {device or '(unnamed)'!r} is on {len(vehicles)} vehicles: {listed}; "
                "a calibration is of one physical IMU: fit each vehicle's logs apart, or "
                "give --pool-vehicles to pool them on purpose")


def check_autopilot_frames(runs: Sequence[Run]) -> None:
    """ConfigError for ArduPilot runs whose rates are not the raw sensor frame: logged with a
    board rotation (``AHRS_ORIENTATION`` ≠ 0: the ``IMU`` message is in the body frame, so
    coefficients would land on the wrong axes of the sensor the export writes for) or
    already corrected (``INS_TCAL<n>_ENABLE`` = 1: a fit would fit the residuals of the
    autopilot's own cubic). ArduPilot's ``Tools/scripts/tempcal_IMU.py`` undoes both;
    gyrotherm does not yet, so it refuses, naming the parameter and how to log instead."""
    for r in runs:
        orientation = _id(r.metadata, "ahrs_orientation")
        if orientation not in ("", "0"):
            raise ConfigError(
                f"{r.source}: {r.name}: AHRS_ORIENTATION = {orientation}: ArduPilot logs the "
                "IMU rates in the body frame, rotated from the sensor's; gyrotherm does not "
                "undo the rotation yet, so the coefficients would be on the wrong axes. Log "
                "the calibration with AHRS_ORIENTATION = 0 (the board's own frame), or fit "
                "with ArduPilot's Tools/scripts/tempcal_IMU.py")
        if _id(r.metadata, "tcal_enable") == "1":
            n = int(_id(r.metadata, "instance") or 0) + 1
            raise ConfigError(
                f"{r.source}: {r.name}: INS_TCAL{n}_ENABLE = 1: the logged rates are already "
                "corrected by the autopilot's temperature calibration, and a fit would fit "
                f"what it leaves. Log the calibration run with INS_TCAL{n}_ENABLE = 0")


def select_devices(runs: Sequence[Run], wanted: Sequence[str] | None) -> list[Run]:
    """``--device``: the runs whose ``device_id`` is one of ``wanted`` (all without it);
    ConfigError naming the devices found when one given matches no run."""
    if not wanted:
        return list(runs)
    found = sorted({_id(r.metadata, "device_id") for r in runs})
    missing = [w for w in wanted if w not in found]
    if missing:
        raise ConfigError(f"--device {', '.join(missing)}: no such device in the inputs; "
                          f"they hold {', '.join(repr(f) for f in found) or 'none named'}")
    return [r for r in runs if _id(r.metadata, "device_id") in wanted]


def recorded(runs: Sequence[Run]) -> dict[str, str]:
    """``sensor_id`` and ``vehicle_id`` the runs agree on (for the provenance)."""
    out = {}
    for key in ("sensor_id", "vehicle_id"):
        values = {_id(r.metadata, key) for r in runs}
        if len(values) == 1 and (value := values.pop()):
            out[key] = value
    return out


def matching_runs(provenance: Mapping[str, Any], runs: Sequence[Run], *, what: str,
                  file: Any = None) -> list[Run]:
    """The runs of the calibration's IMU (module docstring); a note for those left out."""
    want = {k: _id(provenance, k) for k in KEYS}
    if not any(want.values()):
        return list(runs)

    def fits(r: Run) -> bool:
        return all(not want[k] or not _id(r.metadata, k) or _id(r.metadata, k) == want[k]
                   for k in KEYS)

    mine = [r for r in runs if fits(r)]
    if not mine:
        found = sorted({" ".join(f"{k}={_id(r.metadata, k)}" for k in KEYS
                                 if _id(r.metadata, k)) for r in runs})
        named = " ".join(f"{k}={v}" for k, v in want.items() if v)
        raise CalibrationError(f"{what}: no run of the calibration's IMU ({named}); the "
                               f"runs hold: {'; '.join(found)}")
    left = [r.name for r in runs if not fits(r)]
    if left:
        print(f"not used (another IMU or vehicle than the calibration's): {', '.join(left)}",
              file=file or sys.stderr)
    return mine
