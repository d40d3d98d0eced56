"""``gyrotherm fleet LOGS... [--previous DIR] [--out DIR] [--json [FILE]]``: a fleet's
logs in, one calibration per IMU out, and which IMUs drifted since their last one.

The logs (any format ``fit`` reads, of many vehicles) are read and prepared on the
workers (:mod:`._prep`: ``--jobs``, ``--dask-scheduler``); their runs are grouped by
IMU, ``(vehicle_id, device_id, sensor_id)`` as the readers give them
(:mod:`._identity`), in sorted order. Each IMU's runs are fitted as ``fit`` fits one
device (rest rows, its quality gates; an IMU a gate refuses is listed as ``not fitted``
with the reason, the others go on): with none of the estimator options, each IMU's
estimator is chosen from its own runs' temperature readout in a first read pass, and
``--method auto`` picks offsets or pooled from its runs, both as ``fit`` does and
recorded in the provenance (``estimator_chosen``, ``method_chosen``), so an IMU's
calibration is the one ``fit`` writes from the same logs. With ``--previous``, compared
with its previous calibration (:mod:`._drift`: bias shift and held-out residual
against ``--threshold-dps``). ``--out DIR`` writes each calibration to
``DIR/<vehicle>-<device>[-<sensor>].json`` (the identity recorded in its provenance,
so the directory serves as the next run's ``--previous``).

Exit status: 0; 2 when a log could not be read (each named on stderr, the IMUs of
the others reported and written). A drifted or unfitted IMU is a finding, reported in
the table and the JSON (``status``), not an error.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gyrotherm._errors import ConfigError, GyrothermError
from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import _drift, _fitgates, _fitrest, _identity, _pool, _prep
from gyrotherm.cli._common import (
    add_estimator_options,
    estimator_from_args,
    estimator_is_auto,
)
from gyrotherm.cli._inputs import add_input_options
from gyrotherm.codecs import Run
from gyrotherm.compensation import METHODS, MODELS, Calibration, RunFeatures
from gyrotherm.estimators import EstimatorConfig

if TYPE_CHECKING:  # the characterisation is imported when it runs (its numpy/scipy cost)
    from gyrotherm.analysis._readout_estimator import ChosenEstimator, RunReadout

SCHEMA = "gyrotherm.fleet/1"


def _file_name(key: _drift.Key) -> str:
    vehicle, device, sensor = key
    parts = [vehicle or "vehicle", device or "device"] + ([sensor] if sensor and
                                                          sensor != device else [])
    return _fitrest.safe_device_name("-".join(parts)) + ".json"


def _fit_imu(args: argparse.Namespace, est: EstimatorConfig, key: _drift.Key,
             runs: Sequence[Run], feats: list[RunFeatures],
             record: dict[str, Any] | None = None,
             ) -> tuple[Calibration | None, list[RunFeatures], str]:
    """The IMU's calibration (None and the reason when refused) and the runs fitted;
    ``record``: how its estimator was chosen (None: given by the options)."""
    from gyrotherm.cli._offline import _method, _with_estimator_record
    from gyrotherm.compensation import fit
    from gyrotherm.compensation._models import get_model
    from gyrotherm.compensation._quality import check

    feats = _fitrest.drop_restless(feats, file=sys.stderr)
    gates = check(feats, get_model(args.model), validation=False)
    refusing = [g.line() for g in gates if not g.passed and g.refuses]
    if refusing:
        return None, feats, "quality gate: " + "; ".join(refusing)
    try:
        _identity.check_autopilot_frames(runs)
        method, method_chosen = _method(args, feats, label=f"{_label(key)}: ")
        cal = fit(feats, args.model, estimator=est, method=method)
    except GyrothermError as exc:
        return None, feats, str(exc)
    ids = {k: v for k, v in zip(_drift.KEYS, key, strict=True) if v}
    cal = _with_estimator_record(cal, record)
    cal = replace(cal, provenance={**cal.provenance, **ids,
                                   **({"method_chosen": method_chosen} if method_chosen else {})})
    return _fitgates.record(cal, gates), feats, ""


def _label(key: _drift.Key) -> str:
    """How a note names an IMU: vehicle/device[/sensor]."""
    vehicle, device, sensor = key
    return "/".join(p for p in (vehicle or "(no vehicle)", device or "(no device)",
                                sensor if sensor and sensor != device else "") if p)


def _entry(args: argparse.Namespace, est: EstimatorConfig, key: _drift.Key,
           runs: list[Run], feats: list[RunFeatures], previous: list[_drift.Previous],
           out_dir: Path | None, record: dict[str, Any] | None = None) -> dict[str, Any]:
    cal, used, reason = _fit_imu(args, est, key, runs, feats, record)
    entry: dict[str, Any] = {**dict(zip(_drift.KEYS, key, strict=True)),
                             "runs": [f.name for f in used],
                             "logs": sorted({r.source for r in runs})}
    if cal is None:
        return {**entry, "status": "not fitted", "reason": reason, "calibration": None}
    path = None
    if out_dir is not None:
        path = str(cal.save(out_dir / _file_name(key)))
    r = cal.valid_range
    old = _drift.match(key, previous)
    entry = {**entry, "calibration": path, "model": cal.model.name,
             "valid_range_c": [r.t_min_c, r.t_max_c],
             "coefficients_physical": {a: cal.physical_coefficients(a) for a in cal.axes},
             "steady_bias_dps": {a: [cal.base_bias(a, r.t_min_c, 0.0),
                                     cal.base_bias(a, r.t_max_c, 0.0)] for a in cal.axes},
             **_drift.drift(cal, used, old, threshold_dps=args.threshold_dps)}
    if entry.get("previous_estimator_differs") and not args.quiet:
        print(f"note: {_label(key)}: the previous calibration's T/ΔT estimator differs from "
              "this one's; its shift and residual are on T/ΔT estimated with this one",
              file=sys.stderr)
    return entry


def _groups(runs: Sequence[Run], feats: Sequence[RunFeatures]
            ) -> dict[_drift.Key, tuple[list[Run], list[RunFeatures]]]:
    groups: dict[_drift.Key, tuple[list[Run], list[RunFeatures]]] = {}
    for run, f in zip(runs, feats, strict=True):
        g = groups.setdefault(_drift.identity(run.metadata), ([], []))
        g[0].append(run)
        g[1].append(f)
    nameless = sum(len(g[0]) for k, g in groups.items() if not k[0])
    if nameless:
        print(f"note: {nameless} run(s) name no vehicle (no vehicle_id in the log): "
              "grouped by device alone", file=sys.stderr)
    return dict(sorted(groups.items()))


def cmd_fleet(args: argparse.Namespace) -> int:
    conv.check_runs(args.runs, command="fleet")
    conv.check_json_target(args.json)
    if not args.threshold_dps > 0:
        raise ConfigError(f"--threshold-dps {args.threshold_dps}: give a threshold > 0 °/s")
    est = estimator_from_args(args)
    previous = _drift.load_previous(args.previous)
    out_dir = conv.output_dir(args.out, option="--out") if args.out else None
    logs, failed_first = list(args.runs), []
    chosen: dict[_drift.Key, ChosenEstimator] = {}
    auto = estimator_is_auto(args)
    if auto:  # a first pass characterises each IMU's readout
        first = _prep.load(args, _prep.prep_from_args(args, keep_rows=False, readout=True))
        chosen = _chosen(first.runs, first.readouts, quiet=args.quiet)
        logs, failed_first = first.paths, first.failed
    loaded = _prep.load(args, _prep.prep_from_args(
        args, estimator=est, keep_rows=False,
        imu_estimators={k: c.estimator for k, c in chosen.items()}), logs,
        notes=not auto)  # the first pass said the logs' damage
    if failed_first:  # exit 2 once the others are reported
        loaded = replace(loaded, failed=[*failed_first, *loaded.failed])
    feats = _fitrest.mask_motion(loaded.features, loaded.reports)
    imus = [_entry(args, chosen[key].estimator if key in chosen else est, key, runs, fs,
                   previous, out_dir, chosen[key].to_dict() if key in chosen else None)
            for key, (runs, fs) in _groups(loaded.runs, feats).items()]
    if args.json:
        conv.emit_json({"schema": SCHEMA, "threshold_dps": args.threshold_dps,
                        "previous_dir": args.previous, "definitions": _DEFINITIONS,
                        "imus": imus, "failed_logs": loaded.failed}, args.json)
    else:
        from gyrotherm.cli._fleettable import print_fleet

        print_fleet(imus, threshold_dps=args.threshold_dps, previous=bool(args.previous))
    return loaded.exit_status


def _chosen(runs: Sequence[Run], readouts: Sequence[RunReadout], *,
            quiet: bool) -> dict[_drift.Key, ChosenEstimator]:
    """Per IMU of ``runs``, the estimator from its own runs' readouts; said on stderr
    unless ``-q``."""
    from gyrotherm.analysis._readout_estimator import estimator_of

    keys = list(dict.fromkeys(_drift.identity(r.metadata) for r in runs))
    chosen = {k: estimator_of([o for o in readouts if o.imu == k]) for k in keys}
    if not quiet:
        for k, c in chosen.items():
            print(f"note: {_label(k)}: {c.describe()}", file=sys.stderr)
    return chosen


_DEFINITIONS = {
    "shift_dps": "RMS of (new − previous bias) over these logs' rest rows in the common "
                 "temperature range (each at its T, ΔT); max over axes, °/s",
    "residual_dps": "previous calibration on these logs (held out): per run and axis the "
                    "mean of raw − bias at rest; RMS over runs; max over axes, °/s",
    "residual_new_dps": "the same for the new fit (its floor: switch-on offsets)",
    "drifted": "shift_dps or residual_dps above threshold_dps",
    "previous_estimator_differs": "the previous calibration's T/ΔT estimator is not the new "
                                  "one's; shift and residual evaluate it on T/ΔT estimated "
                                  "with the new one (each IMU's is chosen from its readout)",
}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("fleet", help="many vehicles' logs: a calibration per IMU, and which "
                       "drifted since the last one",
                       description=(__doc__ or "").split("\n\n", 1)[1])
    p.add_argument("runs", nargs="+", metavar="LOG",
                   help="logs of any vehicles (any format fit reads)")
    p.add_argument("--previous", metavar="DIR",
                   help="directory of the previous calibrations (*.json, e.g. an earlier "
                   "fleet --out) to compare with (default: none; every IMU is 'new')")
    p.add_argument("--threshold-dps", type=float, default=_drift.DEFAULT_THRESHOLD_DPS,
                   help="drift threshold, °/s, for the bias shift and the held-out "
                   f"residual (default {_drift.DEFAULT_THRESHOLD_DPS:g})")
    p.add_argument("--model", choices=sorted(MODELS), default="paper",
                   help="bias model of the new calibrations (default paper)")
    p.add_argument("--out", metavar="DIR",
                   help="write each IMU's calibration to DIR/<vehicle>-<device>.json "
                   "(created; default: not written)")
    conv.add_json_option(p, what="every IMU: identity, calibration, drift numbers "
                         f"(schema {SCHEMA})")
    p.add_argument("--method", choices=("auto", *METHODS), default="auto",
                   help="as fit's --method, per IMU (default auto: offsets when at least "
                   "half of its runs' temperature variance is within runs, else pooled)")
    add_estimator_options(p, auto=True)
    add_input_options(p)
    _fitrest.add_rest_options(p)
    _pool.add_worker_options(p)
    p.set_defaults(func=cmd_fleet)
