"""The effects state on disk, so that a restarted daemon does not replay the warm-up.

One JSON file per sensor in ``state_dir`` (``<vehicle>.<sensor>.effects-state.json``),
written atomically (a temporary file in the same directory, fsync, rename)::

    {"schema": "gyrotherm.effects-state", "version": 1,
     "vehicle": "veh01", "sensor": "imu0", "calibration_id": "3f2a9c0d41e8b7a2",
     "power_on_s": 1700000000.5, "time_s": 1700003600.2,
     "compensator": {Compensator.state_dict()},
     "zero": {"status": "done", "offset_dps": [x, y, z], "done_s": t}}   # optional

``zero`` (the boot-time zero, present when one is configured) lets a restart
that continues the gyro's run keep a zero that was done, instead of needing the
vehicle at rest again; it is saved with any calibration, with or without effects.

``power_on_s`` and ``time_s`` (the latest compensator step) are on the sensor's
clock, s. The zero's ``start_s`` (s), ``trusted`` and ``unverified`` were added
later; a file without them reads as a trusted zero started at the power-on. The
daemon restores it only for the same vehicle, sensor and calibration id, and only
when its first temperature frame continues ``time_s`` within ``power_on_gap_s``
(:mod:`gyrotherm.daemon._compensation`), and only the parts within their bounds
(:mod:`gyrotherm.daemon._restore`); anything else starts fresh. A file that
cannot be read, is not a regular file of bounded size, or is malformed is logged
(one line naming the file, the field and the problem) and ignored: it is only an
optimisation of the start, never fatal.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm._safefile import read_json_file
from gyrotherm.compensation._zero import check_saved
from gyrotherm.daemon._compensation import Compensation, EffectsSnapshot

log = logging.getLogger("gyrotherm.daemon")

SCHEMA = "gyrotherm.effects-state"
VERSION = 1
#: Largest state file read, bytes (one is about 2 kB).
MAX_STATE_BYTES = 256 * 1024
#: Seconds between two saves from the housekeeping (and one at shutdown).
SAVE_PERIOD_S = 5.0


@dataclass(frozen=True)
class SavedEffects:
    """A state file's content."""

    vehicle: str
    sensor: str
    calibration_id: str
    snapshot: EffectsSnapshot


def state_path(state_dir: Path, vehicle: str, sensor: str) -> Path:
    return state_dir / f"{vehicle}.{sensor}.effects-state.json"


def save(path: Path, saved: SavedEffects) -> None:
    """Write atomically; OSError propagates (the caller logs it)."""
    s = saved.snapshot
    doc = {"schema": SCHEMA, "version": VERSION, "vehicle": saved.vehicle,
           "sensor": saved.sensor, "calibration_id": saved.calibration_id,
           "power_on_s": s.power_on_s, "time_s": s.time_s, "compensator": s.state,
           **({} if s.zero is None else {"zero": s.zero})}
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(json.dumps(doc, allow_nan=False) + "\n")
            f.flush()
            os.fsync(f.fileno())
        tmp.replace(path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise


def _field(doc: dict[str, Any], key: str, kind: type | tuple[type, ...], want: str,
           source: str) -> Any:
    v = doc.get(key)
    if isinstance(v, bool) or not isinstance(v, kind):
        raise CalibrationError(f"{source}: field {key!r}: expected {want}, got {v!r:.60}")
    return v


def load(path: Path) -> SavedEffects | None:
    """The saved state, None when there is no file; CalibrationError (naming the file
    and field) when it is unreadable or malformed. Only a regular file of at most
    :data:`MAX_STATE_BYTES` is read, without blocking, and parsed with bounded depth
    and numbers (:mod:`gyrotherm._safefile`). What the values mean (times, the
    compensator state, the zero's offset) is checked when it is restored
    (:mod:`gyrotherm.daemon._restore`)."""
    doc = read_json_file(path, what="effects state", error=CalibrationError,
                         max_bytes=MAX_STATE_BYTES)
    if doc is None:
        return None
    src = str(path)
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA or doc.get("version") != VERSION:
        raise CalibrationError(f"{src}: expected schema {SCHEMA!r} version {VERSION}")
    times = {}
    for key in ("power_on_s", "time_s"):
        times[key] = float(_field(doc, key, (int, float), "a number", src))
    return SavedEffects(_field(doc, "vehicle", str, "a string", src),
                        _field(doc, "sensor", str, "a string", src),
                        _field(doc, "calibration_id", str, "a string", src),
                        EffectsSnapshot(times["power_on_s"], times["time_s"],
                                        _field(doc, "compensator", dict, "an object", src),
                                        _zero_or_none(doc, src), src))


def _zero_or_none(doc: dict[str, Any], src: str) -> dict[str, Any] | None:
    """The saved zero; a malformed one is logged and dropped alone (the effects state
    is still restored; the zero is then measured again)."""
    if "zero" not in doc:
        return None
    try:
        return check_saved(doc["zero"], src)
    except CalibrationError as exc:
        log.warning("saved boot-time zero ignored (measured again): %s", exc)
        return None


class EffectsKeeper:
    """The daemon's side: restore at start, save every :data:`SAVE_PERIOD_S` and at
    shutdown. Without ``state_dir`` every method does nothing."""

    def __init__(self, state_dir: Path | None, vehicle: str, sensor: str) -> None:
        self.path = None if state_dir is None else state_path(state_dir, vehicle, sensor)
        self._vehicle, self._sensor = vehicle, sensor
        self._last_save_s = -math.inf
        self.saves = 0
        self.failures = 0

    def restore(self, compensation: Compensation, calibration_id: str) -> None:
        """Hand the saved state to ``compensation`` if it is this sensor's and this
        calibration's (whether it continues is decided at the first frame)."""
        if self.path is None or not calibration_id:
            return
        try:
            saved = load(self.path)
        except CalibrationError as exc:
            log.warning("effects state ignored, starting from power-on: %s", exc)
            compensation.note_unusable_state(None)
            return
        if saved is None:
            return
        if (saved.vehicle, saved.sensor, saved.calibration_id) != (
                self._vehicle, self._sensor, calibration_id):
            log.info("effects state in %s is for %s/%s calibration %s, not %s/%s %s: "
                     "starting from power-on", self.path, saved.vehicle, saved.sensor,
                     saved.calibration_id, self._vehicle, self._sensor, calibration_id)
            compensation.note_unusable_state(saved.snapshot)
            return
        compensation.restore_at_power_on(saved.snapshot)

    def save(self, compensation: Compensation, calibration_id: str, now_s: float, *,
             force: bool = False) -> None:
        """Save when :data:`SAVE_PERIOD_S` passed since the last save (``now_s``:
        monotonic), or at once with ``force``; only a calibration with effects, or
        any calibration when a boot-time zero is configured."""
        cal = compensation.calibration
        if (self.path is None or cal is None or (cal.version == 1 and compensation.zero is None)
                or not (force or now_s - self._last_save_s >= SAVE_PERIOD_S)):
            return
        snap = compensation.snapshot()
        if snap is None:
            return
        self._last_save_s = now_s
        try:
            save(self.path, SavedEffects(self._vehicle, self._sensor, calibration_id, snap))
            self.saves += 1
        except (OSError, ValueError) as exc:
            self.failures += 1
            n = self.failures
            if n & (n - 1) == 0:
                log.warning("cannot save the effects state to %s (%d failures): %s",
                            self.path, n, exc)
