"""``gyrotherm export CAL --px4 FILE --ardupilot FILE``: the autopilots' own parameters.

The calibration's model (T and ΔT from the estimator) cannot be loaded into PX4 or
ArduPilot: both evaluate a cubic in the raw temperature reading only
(:mod:`gyrotherm.compensation._autopilot`). Export therefore *refits* their form on the
same data: the runs listed in the calibration's provenance (re-read, each checked
against its sha256; or RUNS given on the command line), rows at rest (``--rest auto``),
pooled least squares of the rate on (T − T_ref)^k, k = 0..3, T = the sensor's reading.
It then prints, per axis, the error left on the validation runs (``--validate RUNS``;
without it the fitting runs, flagged in-sample) by the calibration's model and by the
cubic, in °/s: what the ΔT-free form costs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.cli import _fitrest, _identity
from gyrotherm.cli._inputs import (
    add_input_options,
    load_inputs,
    spec_from_args,
    with_recorded_options,
)
from gyrotherm.cli._jsonsafe import dumps
from gyrotherm.codecs import Run
from gyrotherm.compensation import ErrorMetrics, features, load_calibration
from gyrotherm.compensation._autopilot import (
    CubicT,
    ardupilot_params,
    ardupilot_params_file,
    fit_cubic_t,
    px4_params,
    px4_params_file,
)
from gyrotherm.compensation._calibration import Calibration
from gyrotherm.compensation._rest import RestConfig
from gyrotherm.readers import InputSpec, read_runs


def provenance_runs(cal: Calibration, where: str, spec: InputSpec | None = None) -> list[Run]:
    """The calibration's fitting runs, re-read (a relative path from the working directory,
    else from the calibration's directory) with the input options ``spec``; in a log of
    several IMUs, the run of the entry's name. CalibrationError when one is missing or its
    content changed (sha256)."""
    entries = cal.provenance.get("runs")
    if not isinstance(entries, list) or not entries:
        raise CalibrationError(f"{where}: provenance lists no runs; give the runs: "
                               "gyrotherm export CAL RUNS...")
    out = []
    for e in entries:
        source = str(e.get("source", ""))
        beside = Path(where).parent / source  # a relative path: from the fit's directory
        path = source if Path(source).is_file() else str(beside) if beside.is_file() else ""
        if not path:
            raise CalibrationError(f"{where}: fitting run {source!r} is missing; give the "
                                   "runs on the command line")
        found = read_runs(path, spec=spec or InputSpec())
        named = [r for r in found if r.name == e.get("name")]
        if not named and len(found) != 1:
            raise CalibrationError(f"{where}: fitting run {e.get('name')!r} is not in "
                                   f"{source!r} (it holds {[r.name for r in found]})")
        run = named[0] if named else found[0]
        device = cal.provenance.get("device_id")
        if device is not None and run.metadata.get("device_id", device) != device:
            raise CalibrationError(f"{where}: fitting run {source!r} is device "
                                   f"{run.metadata['device_id']!r}, the calibration {device!r}")
        if run.sha256 != e.get("sha256"):
            raise CalibrationError(f"{where}: fitting run {source!r} changed since the fit "
                                   f"(sha256 {run.sha256[:12]}… ≠ {str(e.get('sha256'))[:12]}…)")
        out.append(run)
    return out


def _of_device(cal: Calibration, runs: list[Run], what: str) -> list[Run]:
    """The runs of the calibration's IMU (device, sensor id and vehicle where recorded:
    :func:`gyrotherm.cli._identity.matching_runs`), from logs that may hold several."""
    return _identity.matching_runs(cal.provenance, runs, what=what)


def _rest_rows(run: Run, mode: str, config: RestConfig | None) -> np.ndarray:
    # fit's own rest decision (_fitrest.rest_of), with the same options
    return np.ones(len(run), dtype=bool) if mode == "all" else \
        _fitrest.rest_of(run, config).rest


MIN_CUBIC_ROWS = 8
"""Rows the cubic in T needs at least (two per coefficient)."""


def fit_cubic(runs: list[Run], mode: str, config: RestConfig | None = None) -> CubicT:
    masks = [_rest_rows(r, mode, config) for r in runs]
    kept = sum(int(m.sum()) for m in masks)
    if kept < MIN_CUBIC_ROWS:
        raise CalibrationError(
            f"{', '.join(sorted({r.source for r in runs}))}: {kept} of "
            f"{sum(len(r) for r in runs)} rows at rest (--rest {mode}), the cubic in T needs "
            f"at least {MIN_CUBIC_ROWS}; give runs with the gyro still, or --rest all if it "
            "was still throughout")
    return fit_cubic_t([r.temperature_c[m] for r, m in zip(runs, masks, strict=True)],
                       [{a: v[m] for a, v in r.rates_dps.items()}
                        for r, m in zip(runs, masks, strict=True)])


#: What the cubic in T is fitted to: ``rows`` (the rates at rest, pooled), ``model`` (the
#: calibration's steady state: its bias at ΔT = 0 over the rows' temperature range), or
#: ``auto`` (the one with the lower held-out error on ``--validate`` runs; ``model``
#: without them).
CUBIC_TARGETS = ("auto", "rows", "model")
_GRID = 256


def steady_state_bias(cal: Calibration, axis: str, temperature_c: np.ndarray) -> np.ndarray:
    """The calibration's bias at ΔT = 0 (°/s): the base polynomial (clamped to its range)
    plus a ``cubic`` effect and a ``correction`` in T (at T) or ΔT (at ΔT = 0); the
    time-dependent effects (warm-up, drift, hysteresis, a correction in t_on) have no place
    in a steady state."""
    t, d, _, _ = cal.clamp(temperature_c, np.zeros_like(temperature_c))
    bias = cal.base_series(axis, t, d)
    effects = cal.effects_of(axis)
    cubic = effects.cubic
    if cubic is not None:
        bias = bias + cubic.coefficient_dps_per_c3 * (t - cubic.t_ref_c) ** 3
    corr = effects.correction
    if corr is not None and corr.variable in ("temperature_c", "delta_t_c"):
        at = temperature_c if corr.variable == "temperature_c" else np.zeros_like(t)
        bias = bias + np.interp(at, corr.knots, corr.values_dps)  # constant beyond the knots
    return np.asarray(bias, dtype=np.float64)


def fit_model_cubic(cal: Calibration, runs: list[Run], mode: str,
                    config: RestConfig | None = None) -> CubicT:
    """The cubic in T fitted to :func:`steady_state_bias` on a grid over the rest rows'
    temperature readings inside the calibration's valid range (where the model is a
    polynomial, not clamped); T_min, T_max are the rows' extremes, as the rows' cubic."""
    temps = [r.temperature_c[_rest_rows(r, mode, config)] for r in runs]
    t = np.concatenate(temps) if temps else np.zeros(0)
    if len(t) < MIN_CUBIC_ROWS:
        raise CalibrationError(f"{len(t)} rows at rest: the cubic in T needs at least "
                               f"{MIN_CUBIC_ROWS}")
    lo, hi = float(t.min()), float(t.max())
    r = cal.valid_range  # where the model is a polynomial (clamped outside): fit there
    grid = np.linspace(max(lo, r.t_min_c), min(hi, r.t_max_c), _GRID)
    if not grid[-1] - grid[0] >= 1.0:
        grid = np.linspace(lo, hi, _GRID)
    fitted = fit_cubic_t([grid], [{a: steady_state_bias(cal, a, grid) for a in cal.axes}])
    return CubicT(fitted.t_ref_c, lo, hi, fitted.coefficients_rad_s)  # the rows' T range


def _mean_cubic_rms(errors: dict[str, dict[str, float]]) -> float:
    return float(np.mean([e["cubic_rms_dps"] for e in errors.values()]))


def validation_errors(cal: Calibration, cubic: CubicT, runs: list[Run],
                      mode: str, config: RestConfig | None = None
                      ) -> dict[str, dict[str, float]]:
    """Per axis, pooled over ``runs`` (rest rows): raw, model and cubic errors, °/s."""
    res: dict[str, dict[str, list[np.ndarray]]] = {}
    for run in runs:
        keep = _rest_rows(run, mode, config)
        if not keep.any():  # nothing to score in this run
            continue
        feats = features(run, cal.estimator)
        for axis in cal.axes:
            if axis not in run.rates_dps or axis not in cubic.coefficients_rad_s:
                continue
            raw = run.rates_dps[axis]
            ours, _ = cal.bias_series(axis, feats.temperature_c, feats.delta_t_c, run.time_s)
            theirs = cubic.bias_dps(axis, run.temperature_c)
            d = res.setdefault(axis, {"raw": [], "model": [], "cubic": []})
            d["raw"].append(raw[keep])
            d["model"].append((raw - ours)[keep])
            d["cubic"].append((raw - theirs)[keep])
    out = {}
    for axis, d in res.items():
        m = {k: ErrorMetrics.of(np.concatenate(v)) for k, v in d.items()}
        out[axis] = {f"{k}_{s}_dps": getattr(e, f"{s}_dps") for k, e in m.items()
                     for s in ("rms", "max_abs")}
    return out


def _device_id(args: argparse.Namespace, cal: Calibration) -> int:
    text = args.device_id if args.device_id is not None else cal.provenance.get("device_id")
    try:
        return int(str(text), 0)
    except ValueError:
        raise ConfigError(f"--px4 needs the gyro's integer device id (PX4's sensor_gyro "
                          f"device_id, TC_G<i>_ID); the calibration has {text!r}: give "
                          "--device-id N") from None


def _instance(args: argparse.Namespace, cal: Calibration) -> int:
    """The slot: ``--instance``, else the IMU instance the calibration recorded (fit writes
    it for a log of several IMUs), else 0; a disagreement with the recorded one is refused."""
    recorded = cal.provenance.get("instance")
    if recorded is not None and (isinstance(recorded, bool) or not isinstance(recorded, int)):
        raise ConfigError(f"{args.calibration}: provenance 'instance' = {recorded!r} is not "
                          "an integer")
    if args.instance is None:
        return 0 if recorded is None else recorded
    if recorded is not None and recorded != args.instance:
        raise ConfigError(f"--instance {args.instance}: the calibration is of IMU instance "
                          f"{recorded} (device {cal.provenance.get('device_id')!r}); its "
                          f"parameters belong in slot {recorded} (drop --instance)")
    return int(args.instance)


def cmd_export(args: argparse.Namespace) -> int:
    if not (args.px4 or args.ardupilot):
        raise ConfigError("export: nothing to write; give --px4 FILE and/or --ardupilot FILE")
    if not 1 <= args.vehicle_id <= 255:
        raise ConfigError(f"--vehicle-id {args.vehicle_id}: a MAVLink system id is 1..255")
    cal = load_calibration(args.calibration)
    where = str(args.calibration)
    args.instance = _instance(args, cal)
    device = _device_id(args, cal) if args.px4 else 0
    fit_runs = _of_device(cal, load_inputs(args), "RUNS") if args.runs else provenance_runs(
        cal, where, spec_from_args(with_recorded_options(args, cal.provenance.get(
            "input_options"))))
    _identity.check_autopilot_frames(fit_runs)
    rest = _fitrest.rest_config(args)
    in_sample = not args.validate
    valid = fit_runs if in_sample else _of_device(cal, load_inputs(args, args.validate),
                                                  "--validate")
    def candidate(name: str) -> CubicT:
        return (fit_cubic(fit_runs, args.rest, rest) if name == "rows"
                else fit_model_cubic(cal, fit_runs, args.rest, rest))

    target = args.cubic_target
    heldout: dict[str, float] = {}
    if target == "auto" and not in_sample:  # measured on the held-out runs
        fitted = {k: candidate(k) for k in ("rows", "model")}
        scored = {k: validation_errors(cal, c, valid, args.rest, rest)
                  for k, c in fitted.items()}
        heldout = {k: _mean_cubic_rms(e) for k, e in scored.items()}
        target = min(heldout, key=lambda k: heldout[k])
        cubic, errors = fitted[target], scored[target]
    else:
        target = "model" if target == "auto" else target
        cubic = candidate(target)
        errors = validation_errors(cal, cubic, valid, args.rest, rest)
    written: dict[str, Any] = {}
    if args.px4:
        params = px4_params(cubic, instance=args.instance, device_id=device)
        _write(args.px4, px4_params_file(params, vehicle_id=args.vehicle_id))
        written["px4"] = {"file": args.px4, "params": {n: v for n, v, _ in params}}
    if args.ardupilot:
        ap = ardupilot_params(cubic, imu=args.instance + 1)
        _write(args.ardupilot, ardupilot_params_file(ap))
        written["ardupilot"] = {"file": args.ardupilot, "params": dict(ap)}
    doc = {"calibration": where, "model": cal.model.name,
           "cubic": {"t_ref_c": cubic.t_ref_c, "t_min_c": cubic.t_min_c,
                     "t_max_c": cubic.t_max_c,
                     "coefficients_rad_s": {a: list(c) for a, c in
                                            cubic.coefficients_rad_s.items()}},
           "instance": args.instance,
           "cubic_target": {"chosen": target, "asked": args.cubic_target,
                            "heldout_cubic_rms_dps": heldout or None},
           "fit_runs": [r.source for r in fit_runs],
           "validation": {"runs": [r.source for r in valid], "in_sample": in_sample,
                          "rest": args.rest, "axes": errors}, **written}
    if args.json is not None:
        text = dumps(doc) + "\n"  # strict JSON: null for NaN, with why
        if args.json == "-":
            sys.stdout.write(text)
            return 0
        _write(args.json, text)
    _print_table(doc, cal)
    return 0


def _write(path: str, text: str) -> None:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text, encoding="utf-8")


def _print_table(doc: dict[str, Any], cal: Calibration) -> None:
    v = doc["validation"]
    c = doc["cubic"]
    print(f"cubic in T (PX4/ArduPilot form): T_ref {c['t_ref_c']:.3f} °C, range "
          f"[{c['t_min_c']:.3f}, {c['t_max_c']:.3f}] °C, fitted on {len(doc['fit_runs'])} runs")
    ct = doc["cubic_target"]
    how = (", ".join(f"{k} {v:.5f}" for k, v in ct["heldout_cubic_rms_dps"].items())
           if ct["heldout_cubic_rms_dps"] else "")
    print(f"fitted to: {ct['chosen']}" + (f" (held-out cubic RMS, °/s: {how})" if how else
          " (the calibration's steady state; --validate RUNS measures both)"
          if ct["asked"] == "auto" else ""))
    for key in ("px4", "ardupilot"):
        if key in doc:
            print(f"wrote {doc[key]['file']} ({len(doc[key]['params'])} parameters)")
    label = "fitting runs, in-sample" if v["in_sample"] else "validation runs"
    print(f"\nError after compensation on {len(v['runs'])} {label} (rows: {v['rest']}), °/s:")
    print(f"{'axis':<5} {'raw RMS':>10} {cal.model.name + ' RMS':>12} {'cubic RMS':>10} "
          f"{'cost':>9} {cal.model.name + ' max':>12} {'cubic max':>10}")
    for axis, e in v["axes"].items():
        print(f"{axis:<5} {e['raw_rms_dps']:10.5f} {e['model_rms_dps']:12.5f} "
              f"{e['cubic_rms_dps']:10.5f} {e['cubic_rms_dps'] - e['model_rms_dps']:+9.5f} "
              f"{e['model_max_abs_dps']:12.5f} {e['cubic_max_abs_dps']:10.5f}")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    e = sub.add_parser("export", help="write PX4 / ArduPilot thermal parameters (a cubic in T "
                       "refitted on the calibration's runs) and what the ΔT-free form costs")
    e.add_argument("calibration", help="calibration file (JSON) written by 'gyrotherm fit'")
    e.add_argument("runs", nargs="*", help="fitting runs (default: the calibration's "
                   "provenance runs, checked against their sha256)")
    e.add_argument("--px4", metavar="FILE", help="write a QGroundControl .params file")
    e.add_argument("--ardupilot", metavar="FILE", help="write a Mission Planner/MAVProxy "
                   ".param file")
    e.add_argument("--instance", type=int, default=None,
                   help="gyro instance: TC_G<i> (PX4), INS_TCAL<i+1> (ArduPilot) (default: "
                   "the IMU instance the calibration recorded, else 0; another one is "
                   "refused)")
    e.add_argument("--vehicle-id", type=int, default=1,
                   help="MAVLink system id written in the QGroundControl .params file's "
                   "first column (default 1; QGC loads a file only onto that vehicle)")
    e.add_argument("--device-id", help="PX4 device id of the gyro, TC_G<i>_ID (default: "
                   "the calibration's provenance device_id when it is an integer)")
    e.add_argument("--validate", nargs="+", metavar="RUN", help="runs to score both forms "
                   "on (default: the fitting runs, in-sample)")
    e.add_argument("--cubic-target", choices=CUBIC_TARGETS, default="auto",
                   help="what the cubic in T is fitted to: rows (the rates at rest), model "
                   "(the calibration at ΔT = 0, its steady state), or auto: the lower held-out "
                   "error on --validate runs, model without them (default auto)")
    e.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE",
                   help="write the parameters and errors as JSON to FILE (stdout when no FILE, "
                   "instead of the table)")
    add_input_options(e)
    _fitrest.add_rest_options(e, use="fit the cubic on and score")
    e.set_defaults(func=cmd_export)
