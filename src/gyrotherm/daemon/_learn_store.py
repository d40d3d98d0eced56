"""The ``[learn]`` mode's files in ``state_dir``: written atomically, read validated.

Two files per IMU::

    <vehicle>.<sensor>.learn-state.json          what was learnt so far
    <vehicle>.<sensor>.learnt-calibration.json   the adopted calibration (once adopted)

The **learning state** (schema ``gyrotherm.learn-state`` version 1; its ``learn`` object
has its own version, :data:`~gyrotherm.compensation._learnstate.STATE_VERSION`)::

    {"schema": "gyrotherm.learn-state", "version": 1, "vehicle": "veh01", "sensor": "imu0",
     "power_ons": 12, "last_time_s": 5321.5,            # sensor clock, s (null: none)
     "last_wall_s": 1.7e9,                # wall clock that frame was received at (null)
     "power_on_time_s": 5100.0,           # the latest power-on's stamp while the daemon
                                          # runs (null: none, or it stopped cleanly)
     "rejected": {"motion": 2, "too_short": 1},          # warm-ups left out, by reason
     "decision": {…} | null,                              # the latest Decision.to_dict()
     "adopted": {"time_s": 1.7e9, "calibration_id": "…"} | null,
     "config": {the [learn] settings} | null,
     "learn": {LearnState.to_dict(): the warm-ups' sufficient statistics}}

The **learnt calibration** is an ordinary calibration file (paper model; version 2 when
effects were learnt, else 1) whose
``provenance`` says where it came from: ``learnt_for`` (vehicle, sensor), the power-ons
used, the temperature coverage, the validation figures (current vs new), the margin, the
adoption time and the gyrotherm version.

**Writing** (:func:`write_atomic`): a temporary file ``.<name>.tmp`` in the same
directory, written and fsync'ed, renamed over the target, then the directory fsync'ed.
A write interrupted at any point (the daemon killed, the disk full, the rename failing)
leaves the previous file whole; a temporary file left behind is never read and is
overwritten by the next write.

**Reading**: bounded and non-blocking (:mod:`gyrotherm._safefile`), every field checked
(:meth:`LearnState.from_dict`; the calibration as any calibration the daemon loads, with
the device check). A file that is malformed, of another schema, or another IMU's
(``vehicle``/``sensor`` or ``provenance.learnt_for`` naming another) is a
:class:`~gyrotherm.CalibrationError` naming the file and field; the daemon then
:func:`quarantine` s it (renamed to ``<name>.refused``, the journal says why) and goes
on without it: it never crashes, and never overrides the configured calibration.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm._safefile import read_json_file
from gyrotherm.compensation import Calibration
from gyrotherm.compensation._learnstate import LearnState
from gyrotherm.daemon._calload import load_daemon_calibration

log = logging.getLogger("gyrotherm.daemon")

SCHEMA = "gyrotherm.learn-state"
VERSION = 1
#: Largest learning state read, bytes (256 warm-ups of three axes: about 400 kB).
MAX_STATE_BYTES = 4 << 20
#: Reasons a warm-up is left out (the state message's ``rejected`` keys).
REASONS = ("motion", "too_short", "clock_jump", "restart", "missed_start")


def state_path(state_dir: Path, vehicle: str, sensor: str) -> Path:
    return state_dir / f"{vehicle}.{sensor}.learn-state.json"


def learnt_path(state_dir: Path, vehicle: str, sensor: str) -> Path:
    return state_dir / f"{vehicle}.{sensor}.learnt-calibration.json"


def write_atomic(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` atomically (module docstring); OSError propagates,
    the previous file intact."""
    tmp = path.with_name(f".{path.name}.tmp")
    data = text.encode("utf-8")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0),
                     0o640)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise
    with contextlib.suppress(OSError):  # the rename itself durable (not on every fs)
        dfd = os.open(path.parent, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def quarantine(path: Path, why: str) -> Path | None:
    """Rename a refused file out of the way (``<name>.refused``, replacing an older one)
    and log why; None when even that failed (it is then ignored where it is)."""
    target = path.with_name(path.name + ".refused")
    try:
        os.replace(path, target)
    except OSError as exc:
        log.warning("%s refused and left in place (cannot rename it: %s): %s", path, exc, why)
        return None
    log.warning("%s refused, moved to %s: %s", path, target.name, why)
    return target


@dataclass
class LearnRecord:
    """The learning state file's content (module docstring)."""

    vehicle: str
    sensor: str
    learn: LearnState
    power_ons: int = 0
    last_time_s: float = math.nan
    last_wall_s: float = math.nan
    """Wall-clock receive time of the frame at ``last_time_s``."""
    power_on_time_s: float = math.nan
    """Stamp of the latest power-on learnt or continued (a restart) while the daemon
    runs; NaN: none, or the daemon stopped cleanly (the learner's docstring)."""
    rejected: dict[str, int] = field(default_factory=dict)
    decision: dict[str, Any] | None = None
    adopted: dict[str, Any] | None = None
    config: dict[str, Any] | None = None
    """The ``[learn]`` settings it was written with (for ``gyrotherm learn status``)."""

    def to_dict(self) -> dict[str, Any]:
        return {"schema": SCHEMA, "version": VERSION, "vehicle": self.vehicle,
                "sensor": self.sensor, "power_ons": self.power_ons,
                "last_time_s": None if math.isnan(self.last_time_s) else self.last_time_s,
                "last_wall_s": None if math.isnan(self.last_wall_s) else self.last_wall_s,
                "power_on_time_s": (None if math.isnan(self.power_on_time_s)
                                       else self.power_on_time_s),
                "rejected": dict(self.rejected), "decision": self.decision,
                "adopted": self.adopted, "config": self.config,
                "learn": self.learn.to_dict()}


def _jsonable(doc: Any) -> Any:
    """Non-finite numbers (a condition number of inf) as null: the file stays JSON."""
    if isinstance(doc, float):
        return doc if math.isfinite(doc) else None
    if isinstance(doc, dict):
        return {k: _jsonable(v) for k, v in doc.items()}
    if isinstance(doc, list | tuple):
        return [_jsonable(v) for v in doc]
    return doc


def save_record(path: Path, record: LearnRecord) -> None:
    write_atomic(path, json.dumps(_jsonable(record.to_dict()), allow_nan=False) + "\n")


def load_record(path: Path, *, vehicle: str, sensor: str,
                axes: tuple[str, ...]) -> LearnRecord | None:
    """The learning state, None without a file; CalibrationError naming the file and
    the field when it is not this IMU's valid state."""
    doc = read_json_file(path, what="learning state", error=CalibrationError,
                         max_bytes=MAX_STATE_BYTES)
    if doc is None:
        return None
    src = str(path)

    def bad(key: str, why: str) -> CalibrationError:
        return CalibrationError(f"{src}: field {key!r}: {why}")

    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else type(doc).__name__
        raise bad("schema", f"expected {SCHEMA!r}, got {got!r:.60} (not a learning state)")
    if doc.get("version") != VERSION:
        raise bad("version", f"expected {VERSION}, got {doc.get('version')!r:.40}")
    if (doc.get("vehicle"), doc.get("sensor")) != (vehicle, sensor):
        raise bad("sensor", f"the state of {doc.get('vehicle')!r:.40}/{doc.get('sensor')!r:.40}, "
                  f"not of this IMU {vehicle!r}/{sensor!r}")
    power_ons = doc.get("power_ons")
    if isinstance(power_ons, bool) or not isinstance(power_ons, int) or power_ons < 0:
        raise bad("power_ons", f"expected a count, got {power_ons!r:.40}")
    times = {}
    for key in ("last_time_s", "last_wall_s", "power_on_time_s"):  # absent: null
        v = doc.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v)):
            raise bad(key, f"expected a finite number or null, got {v!r:.40}")
        times[key] = math.nan if v is None else float(v)
    rejected = doc.get("rejected")
    if not (isinstance(rejected, dict) and set(rejected) <= set(REASONS) and all(
            isinstance(v, int) and not isinstance(v, bool) and v >= 0
            for v in rejected.values())):
        raise bad("rejected", f"expected counts by reason among {list(REASONS)}, got "
                  f"{rejected!r:.80}")
    for key in ("decision", "adopted", "config"):
        if doc.get(key) is not None and not isinstance(doc.get(key), dict):
            raise bad(key, f"expected an object or null, got {doc.get(key)!r:.40}")
    _check_decision(doc.get("decision"), bad)
    adopted = doc.get("adopted")
    if adopted is not None and not (isinstance(adopted.get("time_s"), int | float)
                                    and isinstance(adopted.get("calibration_id"), str)):
        raise bad("adopted", f"expected time_s and calibration_id, got {adopted!r:.80}")
    learn = LearnState.from_dict(doc.get("learn"), source=f"{src}: learn")
    if learn.axes != axes:
        raise bad("learn.axes", f"{list(learn.axes)}, not this IMU's {list(axes)}")
    return LearnRecord(vehicle, sensor, learn, power_ons, times["last_time_s"],
                       times["last_wall_s"], times["power_on_time_s"], dict(rejected),
                       doc.get("decision"), adopted, doc.get("config"))


def _check_decision(decision: dict[str, Any] | None, bad: Any) -> None:
    """The fields of a saved :meth:`Decision.to_dict` that the status reads (the learner's
    :func:`progress`, ``gyrotherm learn status``): ``reasons`` a list of text, the
    held-out figures per axis numbers (null: not finite when written)."""
    if decision is None:
        return
    reasons = decision.get("reasons")
    if reasons is not None and not (isinstance(reasons, list)
                                    and all(isinstance(r, str) for r in reasons)):
        raise bad("decision.reasons", f"expected a list of text, got {reasons!r:.60}")
    for key in ("candidate_heldout_rms_dps", "current_heldout_rms_dps"):
        per_axis = decision.get(key)
        if per_axis is not None and not (isinstance(per_axis, dict) and all(
                v is None or (isinstance(v, int | float) and not isinstance(v, bool))
                for v in per_axis.values())):
            raise bad(f"decision.{key}", f"expected numbers per axis, got {per_axis!r:.60}")


def calibration_text(cal: Calibration) -> tuple[str, str]:
    """The calibration file's text and its id (the first 16 hex digits of its sha256,
    as :func:`gyrotherm.compensation.read_calibration` computes it)."""
    text = json.dumps(_jsonable(cal.to_dict()), indent=2, allow_nan=False) + "\n"
    return text, hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def load_learnt(path: Path, *, vehicle: str, sensor: str, device_id: str | None,
                device_mismatch: str) -> tuple[Calibration, str] | None:
    """The adopted learnt calibration and its id, None without a file; CalibrationError
    when it is unusable or not this IMU's (``provenance.learnt_for``)."""
    if not os.path.lexists(path):
        return None
    cal, cid = load_daemon_calibration(path, device_id=device_id,
                                       device_mismatch=device_mismatch)
    owner = cal.provenance.get("learnt_for")
    if owner != {"vehicle": vehicle, "sensor": sensor}:
        raise CalibrationError(f"{path}: field 'provenance.learnt_for' = {owner!r:.80}: not a "
                               f"calibration learnt for {vehicle!r}/{sensor!r}")
    return cal, cid


__all__ = ["REASONS", "LearnRecord", "calibration_text", "learnt_path", "load_learnt",
           "load_record", "quarantine", "save_record", "state_path", "write_atomic"]
