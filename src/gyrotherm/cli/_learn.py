"""``gyrotherm learn LOGS... --out CAL``: a calibration from ordinary power-ons, no chamber.

Every log must start at the gyro's power-on (time since boot: PX4 ``SDLOG_MODE`` 1 or 2,
ArduPilot ``LOG_DISARMED`` = 1, the simulator's runs) and be one IMU. From each, the
warm-up at rest before the vehicle first moves (rest detection as ``fit``'s) is reduced to
its sufficient statistics (:mod:`gyrotherm.compensation._learn`); the candidate paper model
is validated leave-one-power-on-out against ``--current`` (default: no compensation) and
written only when it is better by the margin on every axis and every gate passes. A log
without a usable warm-up is named with the reason and left out; nothing adopted → exit 2
with the reasons (learning goes on: bring more power-ons).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import _fitrest, _identity
from gyrotherm.cli._common import add_estimator_options, estimator_from_args
from gyrotherm.cli._inputs import add_input_options, load_inputs
from gyrotherm.compensation import features, load_calibration
from gyrotherm.compensation._learn import (
    ADOPT_MARGIN,
    GATES,
    WarmupStats,
    decide,
    learnt_calibration,
)


def cmd_learn(args: argparse.Namespace) -> int:
    conv.check_runs(args.runs, command="learn")
    conv.check_json_target(args.json)
    current = load_calibration(args.current) if args.current else None
    est = current.estimator if current is not None else estimator_from_args(args)
    runs = load_inputs(args)
    _identity.check_vehicles(runs, pool=False)
    _identity.check_autopilot_frames(runs)
    devices = {r.metadata.get("device_id", "") for r in runs}
    if len(devices) > 1:
        raise ConfigError(f"learn learns one IMU: these logs hold {len(devices)} "
                          f"({', '.join(sorted(repr(d) for d in devices))}); select one with "
                          "--device")
    reports = _fitrest.rest_reports(args, runs)
    feats = _fitrest.mask_motion([features(r, est) for r in runs], reports)
    stats: list[WarmupStats] = []
    skipped: list[dict[str, str]] = []
    for f in feats:
        try:
            stats.append(WarmupStats.from_features(f))
        except CalibrationError as exc:
            skipped.append({"run": f.name, "reason": str(exc)})
            print(f"learn: left out: {exc}", file=sys.stderr)
    axes = tuple(a for a in ("x", "y", "z") if all(a in f.rates_dps for f in feats))
    decision = decide(stats, current, axes, margin=args.margin)
    out: dict[str, Any] = {"warmups": [{"run": w.name, "rows": w.n, "start_c": w.start_c,
                                        "t_range_c": list(w.t_range_c)} for w in stats],
                           "skipped": skipped, "decision": decision.to_dict(),
                           "gates": dict(GATES), "margin": args.margin}
    if decision.adopt:
        cal = learnt_calibration(stats, axes, estimator=est, decision=decision,
                                 provenance={"current": str(args.current or "none")})
        path = cal.save(conv.output_path(args.out, option="--out"))
        out["calibration"] = str(path)
    if args.json:
        conv.emit_json(out, args.json)
    else:
        _say(out, decision.adopt, quiet=args.quiet)
    return 0 if decision.adopt else 2


def _say(out: dict[str, Any], adopted: bool, *, quiet: bool) -> None:
    d = out["decision"]
    if not quiet:
        for w in out["warmups"]:
            print(f"warm-up {w['run']}: {w['rows']} rows at rest, from {w['start_c']:.1f} °C, "
                  f"T {w['t_range_c'][0]:.1f}…{w['t_range_c'][1]:.1f} °C")
    print(f"{d['warmups']} warm-ups, start temperatures spread {d['start_span_c']:.1f} °C")
    for reason in d["reasons"]:
        print(f"  {reason}")
    if adopted:
        print(f"wrote {out['calibration']}")
    else:
        print("nothing adopted: learning goes on (more power-ons, from other temperatures)")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("learn", help="learn a calibration from power-ons at rest (no chamber)")
    p.add_argument("runs", nargs="+", help="logs of one IMU, each from its power-on (time "
                   "since boot)")
    p.add_argument("--out", required=True, metavar="FILE",
                   help="calibration FILE written when the learnt one is adopted")
    p.add_argument("--current", metavar="CAL.json",
                   help="the calibration in use: the learnt one must beat it on held-out "
                   "warm-ups (default: none, i.e. no compensation; its estimator is used)")
    p.add_argument("--margin", type=float, default=ADOPT_MARGIN,
                   help="held-out RMS must be ≤ (1 − margin) × the current one's, every axis "
                   f"(default {ADOPT_MARGIN:g})")
    conv.add_json_option(p, what="the warm-ups, the logs left out, the decision")
    add_estimator_options(p)
    add_input_options(p)
    _fitrest.add_rest_options(p)
    p.set_defaults(func=cmd_learn)
