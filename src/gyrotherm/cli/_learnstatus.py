"""``gyrotherm learn status --state-dir DIR [--json [FILE]]``: where the daemon's
``[learn]`` mode stands, from its files in ``state_dir`` (no daemon needed).

Per IMU with a learning state (``<vehicle>.<sensor>.learn-state.json``, read and
validated as the daemon reads it, :mod:`gyrotherm.daemon._learn_store`): the status line
the state message carries, the warm-ups used and left out by reason, the temperature
range covered, the spread of the start temperatures, the latest held-out validation
(learnt vs in use, per axis) with its reasons, and the adopted calibration (its id, the
power-ons it was learnt from, its coverage) when there is one. A learnt calibration the
daemon would refuse is reported with the reason. Exit 0 when at least one IMU's state
was read, 1 when the directory holds none, 2 when one could not be read (named).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm._safefile import read_json_file
from gyrotherm.cli import _conventions as conv
from gyrotherm.daemon import _learn_store as store
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.daemon._learner import progress

_SUFFIX = ".learn-state.json"


def _num(v: float) -> float | None:
    return v if math.isfinite(v) else None


def imu_status(path: Path) -> dict[str, Any]:
    """One IMU's status from its learning state file; CalibrationError when unreadable."""
    raw = read_json_file(path, what="learning state", error=CalibrationError,
                         max_bytes=store.MAX_STATE_BYTES)
    if not isinstance(raw, dict) or not isinstance(raw.get("learn"), dict):
        raise CalibrationError(f"{path}: not a learning state")
    vehicle, sensor = str(raw.get("vehicle")), str(raw.get("sensor"))
    axes = raw["learn"].get("axes")  # not a list of text: load_record names the field
    axes = tuple(axes) if isinstance(axes, list) and all(isinstance(a, str) for a in axes) else ()
    record = store.load_record(path, vehicle=vehicle, sensor=sensor, axes=axes)
    assert record is not None
    try:
        config = LearnConfig(**(record.config or {}))
    except (ConfigError, TypeError):
        config = LearnConfig()
    learnt_file = store.learnt_path(path.parent, vehicle, sensor)
    learnt: dict[str, Any] | None = None
    refused = ""
    try:
        found = store.load_learnt(learnt_file, vehicle=vehicle, sensor=sensor, device_id=None,
                                  device_mismatch="warn")
    except CalibrationError as exc:
        found, refused = None, str(exc)
    if found is not None:
        cal, cid = found
        prov = cal.provenance
        learnt = {"path": str(learnt_file), "calibration_id": cid,
                  "adopted_utc": prov.get("adopted_utc"),
                  "power_ons": [p.get("name") for p in prov.get("power_ons", [])
                                if isinstance(p, dict)],
                  "coverage_c": prov.get("coverage_c"), "validation": prov.get("validation")}
    p = progress(record, config, adopted=found is not None and record.adopted is not None)
    ws = record.learn.warmups
    return {"vehicle": vehicle, "sensor": sensor, "status": p.status,
            "warmups_used": p.warmups_used, "need_warmups": p.need_warmups,
            "rejected": dict(p.rejected), "power_ons": record.power_ons,
            "t_range_c": [_num(p.t_min_c), _num(p.t_max_c)],
            "start_span_c": (max(w.start_c for w in ws) - min(w.start_c for w in ws)
                             if ws else 0.0),
            "warmups": [{"name": w.name, "rows": w.n, "start_c": w.start_c,
                         "t_range_c": list(w.t_range_c)} for w in ws],
            "decision": record.decision, "learnt_calibration": learnt,
            "learnt_refused": refused or None, "config": config.to_dict()}


def cmd_learn_status(args: argparse.Namespace) -> int:
    state_dir = Path(args.state_dir)
    if not state_dir.is_dir():
        raise ConfigError(f"--state-dir {state_dir}: not a directory")
    files = sorted(state_dir.glob(f"*{_SUFFIX}"))
    out: list[dict[str, Any]] = []
    failed = []
    for f in files:
        try:
            out.append(imu_status(f))
        except CalibrationError as exc:
            failed.append(str(exc))
            out.append({"file": str(f), "error": str(exc)})
    if args.json:
        conv.emit_json({"state_dir": str(state_dir), "imus": out}, args.json)
    else:
        for item in out:
            _say(item)
        if not files:
            print(f"{state_dir}: no learning state (is [learn] on, has the daemon seen a "
                  "power-on?)")
    return 2 if failed else (0 if files else 1)


def _range(v: Any) -> str:
    if isinstance(v, list) and len(v) == 2 and all(isinstance(x, int | float) for x in v):
        return f"{v[0]:.1f} … {v[1]:.1f} °C"
    return "unknown"


def _say(s: dict[str, Any]) -> None:
    if "error" in s:
        print(f"{s['file']}: cannot be read: {s['error']}")
        return
    print(f"{s['vehicle']}/{s['sensor']}: {s['status']}")
    left = ", ".join(f"{k} {v}" for k, v in sorted(s["rejected"].items())) or "none"
    lo, hi = s["t_range_c"]
    cover = "none yet" if lo is None else f"{lo:.1f} … {hi:.1f} °C"
    print(f"  power-ons {s['power_ons']}, warm-ups used {s['warmups_used']}, left out: {left}")
    print(f"  temperature covered {cover}; start temperatures span {s['start_span_c']:.1f} °C")
    d = s["decision"] or {}
    cand, cur = d.get("candidate_heldout_rms_dps"), d.get("current_heldout_rms_dps")
    pairs = [(a, cand[a], cur[a]) for a in cand if a in cur and None not in (
        cand[a], cur[a])] if cand and cur else []  # null: not finite when written
    if pairs:
        print("  held-out bias error, learnt vs in use: " + ", ".join(
            f"{a} {x:.4f} vs {y:.4f}" for a, x, y in pairs) + " °/s")
    for reason in d.get("reasons") or ():
        print(f"  {reason}")
    learnt = s["learnt_calibration"]
    if learnt is not None:
        print(f"  learnt calibration {learnt['calibration_id']} ({learnt['path']}), adopted "
              f"{learnt['adopted_utc']}, from {len(learnt['power_ons'])} power-ons, "
              f"coverage {_range(learnt['coverage_c'])}")
    if s["learnt_refused"]:
        print(f"  learnt calibration refused: {s['learnt_refused']}")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("learn-status", help="where the daemon's [learn] mode stands (also: "
                       "gyrotherm learn status)")
    p.add_argument("--state-dir", required=True, metavar="DIR",
                   help="the daemon's state_dir (e.g. /var/lib/gyrotherm)")
    conv.add_json_option(p, what="per IMU: status, warm-ups, validation, learnt calibration")
    p.set_defaults(func=cmd_learn_status)
