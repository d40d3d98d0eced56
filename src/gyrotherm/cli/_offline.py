"""``gyrotherm sim chamber``, ``gyrotherm fit``, ``gyrotherm evaluate``, ``gyrotherm paper``."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from gyrotherm._errors import ConfigError
from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import _fitgates, _fitrest, _identity, _paper, _pool, _prep
from gyrotherm.cli._common import (
    add_estimator_options,
    estimator_from_args,
    estimator_is_auto,
    progress,
)
from gyrotherm.cli._inputs import add_input_options, load_inputs, recorded_options
from gyrotherm.cli._tables import coefficient_table, score_table
from gyrotherm.cli._zero import add_zero_option, zero_option, zero_report
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import (
    METHODS,
    MODELS,
    Calibration,
    RunFeatures,
    ZeroConfig,
    default_scaling,
    features,
    fit,
    fit_per_run,
    leave_one_out,
    load_calibration,
    removed_bias,
    score,
)
from gyrotherm.compensation._fit import Method
from gyrotherm.compensation._fit_offsets import WITHIN_SHARE_MIN, choose_method
from gyrotherm.compensation._quality import Gate
from gyrotherm.estimators import EstimatorConfig

if TYPE_CHECKING:  # the analysis package is loaded only when fit chooses the estimator
    from gyrotherm.analysis._readout_estimator import ChosenEstimator, RunReadout

# gyrotherm.sim (and scipy.signal with it) is imported inside the commands that
# simulate: building the parser must not load the simulator (``gyrotherm run`` builds
# it too; tests/cli/test_footprint.py).
PROFILE_NAMES = ("default", "tang2013", "bmi270")  # = gyrotherm.sim._profiles.PROFILE_NAMES


def cmd_sim_chamber(args: argparse.Namespace) -> int:
    from gyrotherm.sim import PAPER_HEATING_MIN, chamber_runs
    from gyrotherm.sim._profiles import get_profile

    profile = get_profile(args.profile)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    heating_min = list(PAPER_HEATING_MIN) if args.heating_min is None else args.heating_min
    runs = chamber_runs(heating_min, seed=args.seed, rate_hz=args.rate_hz,
                        hold_s=args.hold_s, validation=args.validation,
                        gyro=profile.gyro, chamber=profile.chamber,
                        progress=progress("simulating", quiet=args.quiet))
    return write_runs(runs, out, args.json)


def write_runs(runs: Sequence[Run], out: Path, json_target: str | None) -> int:
    """Write ``runs`` as run files in ``out``: a line each, or ``--json``'s list."""
    written = []
    for run in runs:
        path = write_run(run, out / f"{run.name}.csv")
        written.append({"path": str(path), "rows": len(run), "duration_s": run.duration_s})
        if not json_target:
            print(f"wrote {path} ({len(run)} rows, {run.duration_s / 3600:.2f} h)")
    if json_target:
        conv.emit_json({"runs": written}, json_target)
    return 0


def _features_of(runs: list[Run], est: EstimatorConfig, *, quiet: bool) -> list[RunFeatures]:
    report = progress("estimating T and ΔT", quiet=quiet)
    out = []
    for i, run in enumerate(runs):
        out.append(features(run, est))
        report(i + 1, len(runs))
    return out


def cmd_fit(args: argparse.Namespace) -> int:
    """Rest detection and one calibration per device: :mod:`gyrotherm.cli._fitrest`."""
    est = estimator_from_args(args)
    names = _effect_names(args)
    conv.check_runs(args.runs, command="fit")
    conv.check_json_target(args.json)
    logs, failed_first = list(args.runs), []
    chosen: dict[str, ChosenEstimator] = {}  # per device, when fit chooses
    auto = estimator_is_auto(args)
    if auto:  # a first pass characterises the readouts
        first = _prep.load(args, _prep.prep_from_args(args, keep_rows=False, readout=True))
        chosen = _chosen_estimators(first.runs, first.readouts, quiet=args.quiet)
        logs, failed_first = first.paths, first.failed
    ests = {device: c.estimator for device, c in chosen.items()}
    # read, rest detection and T/ΔT per log on the workers (--jobs, --dask-scheduler)
    loaded = _prep.load(args, _prep.prep_from_args(args, estimator=est, keep_rows=False,
                                                   device_estimators=ests), logs,
                        notes=not auto)  # the first pass said the logs' damage
    if failed_first:  # the logs the first pass could not read: exit 2 once the rest is written
        loaded = replace(loaded, failed=[*failed_first, *loaded.failed])
    runs = loaded.runs  # headers: metadata, no rows
    _identity.check_vehicles(runs, pool=args.pool_vehicles)
    _identity.check_autopilot_frames(runs)
    reports = loaded.reports
    if names:
        _fitrest.refuse_motion(reports, command="fit --effects")
    feats = _fitrest.mask_motion(loaded.features, reports)
    groups = {device: _fitrest.drop_restless(group, file=sys.stderr)
              for device, group in _fitrest.device_groups(runs, feats).items()}
    paths = {device: conv.output_path(_fitrest.calibration_path(args.out, device, len(groups)),
                                      option="--out") for device in groups}
    with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext():
        _fitrest.print_rest_report(reports)
    gates = {device: _fitgates.gate(args, group, device) for device, group in groups.items()}
    if names:
        if len(groups) > 1:
            raise ConfigError(f"--effects fits one device: these runs hold {len(groups)} "
                              f"({', '.join(repr(g) for g in groups)}); fit each apart")
        device = next(iter(groups))
        return _fit_effects(args, ests.get(device, est), feats, names, gates[device],
                            record=_estimator_record(chosen, device)) or loaded.exit_status
    instances = _instances(runs)
    ids = {device: _identity.recorded([r for r in runs
                                       if r.metadata.get("device_id", "") == device])
           for device in groups}
    written = [_fit_device(args, ests.get(device, est), group, device, paths[device],
                           gates[device], several=len(groups) > 1,
                           instance=instances.get(device), ids=ids[device],
                           record=_estimator_record(chosen, device))
               for device, group in groups.items()]
    if args.json:
        conv.emit_json({"rest": {"mode": args.rest, "runs": [r.to_dict() for r in reports]},
                        "calibrations": written,
                        **({k: written[0][k] for k in _SINGLE_KEYS} if len(written) == 1 else {})},
                       args.json)
    return loaded.exit_status  # 2 when a log failed (the others' calibrations written)


_SINGLE_KEYS = ("calibration", "model", "method", "coefficients_physical", "per_run",
                "leave_one_run_out", "quality")
"""With one device, ``--json`` also has its calibration's keys at the top level."""


def _chosen_estimators(runs: Sequence[Run], readouts: Sequence[RunReadout], *,
                       quiet: bool) -> dict[str, ChosenEstimator]:
    """Per device of ``runs`` (their ``device_id``, "" when absent), the estimator from
    the readouts of its own runs (none of the estimator options given): each device's
    calibration is what ``fit --device ID`` writes for it. Said on stderr unless ``-q``."""
    from gyrotherm.analysis._readout_estimator import estimator_of

    devices = list(dict.fromkeys(str(r.metadata.get(_fitrest.DEVICE_KEY, "") or "")
                                 for r in runs))
    chosen = {d: estimator_of([r for r in readouts if r.device == d]) for d in devices}
    if not quiet:
        for d, c in chosen.items():
            print(f"note: {_device_label(d) if len(chosen) > 1 else ''}{c.describe()}",
                  file=sys.stderr)
    return chosen


def _device_label(device: str) -> str:
    """How a note names the device it is about, when there are several."""
    return f"device {device}: " if device else "the runs without a device id: "


def _estimator_record(chosen: dict[str, ChosenEstimator], device: str) -> dict[str, Any] | None:
    """The provenance of ``device``'s estimator choice (None: an option gave it)."""
    return chosen[device].to_dict() if device in chosen else None


def _method(args: argparse.Namespace, feats: Sequence[RunFeatures], *,
            label: str = "") -> tuple[Method, dict[str, Any] | None]:
    """``--method``, with ``auto`` resolved on the runs (:func:`choose_method`), said on
    stderr unless ``-q`` (after ``label``, the device when there are several); and, for ``auto``,
    how it was resolved (the provenance's ``method_chosen``)."""
    if args.method != "auto":
        return cast(Method, args.method), None
    method, share = choose_method(feats)
    why = ("each run spans temperature: one offset per run" if method == "offsets" else
           "isothermal runs: the T terms come from the levels between runs, one intercept")
    if not args.quiet:
        print(f"note: {label}method {method}: "
              f"{share:.0%} of the temperature variance is within "
              f"runs ({why})", file=sys.stderr)
    return cast(Method, method), {"rule": "--method auto", "within_run_share": share,
                                  "offsets_from_share": WITHIN_SHARE_MIN}


def _with_estimator_record(cal: Calibration, record: dict[str, Any] | None) -> Calibration:
    """``cal`` with the provenance's ``estimator_chosen`` (``record``: how the readout
    chose it), or ``estimator_options`` (None: given on the command line)."""
    key = "estimator_chosen" if record is not None else "estimator_options"
    return replace(cal, provenance={**cal.provenance, key: record or "given"})


def _instances(runs: list[Run]) -> dict[str, int]:
    """Per device id, the instance its log gives it (PX4 uORB instance, ArduPilot IMU
    number from 0, a CSV's device order) when every run of the device agrees."""
    seen: dict[str, set[str]] = {}
    for r in runs:
        seen.setdefault(r.metadata.get("device_id", ""), set()).add(
            r.metadata.get("instance", ""))
    return {d: int(next(iter(v))) for d, v in seen.items()
            if len(v) == 1 and next(iter(v)).isdigit()}


def _fit_device(args: argparse.Namespace, est: EstimatorConfig, feats: list[RunFeatures],
                device: str, out: Path, gates: list[Gate], *, several: bool,
                instance: int | None = None,
                ids: dict[str, str] | None = None,
                record: dict[str, Any] | None = None) -> dict[str, Any]:
    """Fit, print (unless ``--json``) and save the calibration of one device, and its
    report; what was written. ``instance`` (the log's number for the IMU) is recorded in
    the provenance, where ``export`` takes its slot from."""
    if device and not args.json:
        print(f"device {device}: {len(feats)} runs")
    method, method_chosen = _method(args, feats,
                                    label=_device_label(device) if several else "")
    cal = fit(feats, args.model, estimator=est, method=method)
    if method_chosen:
        cal = replace(cal, provenance={**cal.provenance, "method_chosen": method_chosen})
    if device:
        cal = replace(cal, provenance={**cal.provenance, "device_id": device})
    if device and instance is not None:
        cal = replace(cal, provenance={**cal.provenance, "instance": instance})
    if ids:  # the IMU's sensor id and the vehicle, where the logs say
        cal = replace(cal, provenance={**cal.provenance, **ids})
    if recorded_options(args):
        cal = replace(cal, provenance={**cal.provenance, "input_options": recorded_options(args)})
    cal = _fitgates.record(_with_estimator_record(cal, record), gates)
    scaling = default_scaling(feats)
    per_run = fit_per_run(feats, args.model, estimator=est, scaling=scaling) if len(feats) > 1 \
        else []
    for axis in cal.axes if not args.json else ():
        rows = [(f.name, c) for f, c in zip(feats, per_run, strict=False)]
        rows.append((method, cal))
        print(coefficient_table(rows, axis))
        print()
    cal.save(out)
    if not args.json:
        print(f"wrote {out} (model {args.model}, method {method}, "
              f"axes {','.join(cal.axes)})")
    held = []
    if len(feats) > 1 and not args.no_validation:
        held = leave_one_out(feats, args.model, estimator=est, method=method,
                             progress=progress("leave-one-run-out", quiet=args.quiet))
        if not args.json:
            print("\nLeave-one-run-out validation (each run scored by a fit without it):")
            print(score_table([s for h in held for s in h.scores]))
    if args.report:
        report_dir = (Path(args.report) / _fitrest.safe_device_name(device) if several
                      else args.report)
        _report(args, cal, feats, title=f"fit: {args.model}, {method}",
                calibration_path=str(out), report_dir=str(report_dir))
    return {"device": device or None, "calibration": str(out), "path": str(out),
            "model": args.model, "method": method, "axes": list(cal.axes),
            "runs": [f.name for f in feats],
            "coefficients_physical": {a: cal.physical_coefficients(a) for a in cal.axes},
            "per_run": {f.name: {a: c.physical_coefficients(a) for a in c.axes}
                        for f, c in zip(feats, per_run, strict=False)},
            "leave_one_run_out": [s.to_dict() for h in held for s in h.scores],
            "quality": [g.to_dict() for g in gates]}


def _report(args: argparse.Namespace, cal: Calibration, feats: list[RunFeatures], *,
            title: str, calibration_path: str, report_dir: str | None = None,
            zero: ZeroConfig | None = None) -> None:
    """``--report DIR``: per-axis figures and report.md (matplotlib, loaded here only)."""
    from gyrotherm.cli._plots import write_fit_report

    md = write_fit_report(cal, feats,
                          conv.output_dir(report_dir or args.report, option="--report"),
                          title=title, calibration_path=calibration_path, zero=zero)
    if not args.quiet:
        print(f"wrote {md}", file=sys.stderr)


def _effect_names(args: argparse.Namespace) -> tuple[str, ...]:
    """``--effects a,b``: checked before any run is read."""
    from dataclasses import fields

    from gyrotherm.compensation._effects import Effects

    if not args.effects:
        return ()
    known = [f.name for f in fields(Effects)]
    names = [n.strip() for n in args.effects.split(",") if n.strip()]
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise ConfigError(f"--effects {args.effects!r}: unknown {bad or 'empty list'}; "
                          f"known: {', '.join(known)}")
    if args.model != "paper" or args.method not in ("auto", "offsets"):
        raise ConfigError("--effects extends the paper model fitted with one offset per "
                          f"run: not --model {args.model} --method {args.method}")
    return tuple(n for n in known if n in names)


def _fit_effects(args: argparse.Namespace, est: EstimatorConfig, feats: list[RunFeatures],
                 names: tuple[str, ...], gates: list[Gate], *,
                 record: dict[str, Any] | None = None) -> int:
    """``fit --effects``: the paper model plus named effects on every axis, their
    nonlinear parameters searched per axis as the diagnosis does; a version-2 file."""
    from gyrotherm.analysis._to_calibration import fit_effects
    from gyrotherm.compensation._fit import common_axes

    result = fit_effects(feats, {a: names for a in common_axes(feats)}, estimator=est,
                         provenance={"effects_requested": list(names)})
    cal = _fitgates.record(_with_estimator_record(result.calibration, record), gates)
    for axis in cal.axes if not args.json else ():
        print(f"axis {axis}: paper+{'+'.join(names)}: leave-one-run-out RMS (1-s blocks) "
              f"{result.baseline_heldout_rms_dps[axis]:.5g} (paper) → "
              f"{result.heldout_rms_dps[axis]:.5g} °/s")
        for name, params in cal.effects_of(axis).to_params().items():
            print(f"  {name}: " + ", ".join(f"{k} = {v:.6g}" if v is not None else f"{k} = -"
                                            for k, v in params.items()))
    cal.save(args.out)
    if args.json:
        conv.emit_json({"calibration": str(args.out), "version": cal.version,
                        "effects": list(names),
                        "heldout_rms_dps": dict(result.heldout_rms_dps),
                        "baseline_heldout_rms_dps": dict(result.baseline_heldout_rms_dps),
                        "effects_params": {a: cal.effects_of(a).to_params()
                                           for a in cal.axes}}, args.json)
    else:
        print(f"wrote {args.out} (version {cal.version}, model paper+{'+'.join(names)}, "
              f"axes {','.join(cal.axes)})")
    if args.report:
        _report(args, cal, feats, title=f"fit: paper+{'+'.join(names)}",
                calibration_path=str(args.out))
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    conv.check_calibration_first(args.calibration, args.runs, command="evaluate")
    conv.check_json_target(args.json)
    cal = load_calibration(args.calibration)
    runs = _identity.matching_runs(cal.provenance, load_inputs(args), what=str(args.calibration))
    reports = _fitrest.rest_reports(args, runs)
    feats = _fitrest.mask_motion(_features_of(runs, cal.estimator, quiet=args.quiet), reports)
    with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext():
        _fitrest.print_rest_report(reports, use="the scores")
    zero = zero_option(args)
    removed = [removed_bias(cal, f, zero=zero) for f in feats]
    scores = _fitrest.scored_at_rest([s for f, rb in zip(feats, removed, strict=True)
                      for s in score(cal, f, removed=rb)], args)
    zeros = [zero_report(f, rb.zero) for f, rb in zip(feats, removed, strict=True)
             if rb.zero is not None]
    effects = {a: list(cal.effect_names(a)) for a in cal.axes}
    start = ("each run's first row (power-on: the effects' runtime state starts there, "
             "t_on = the run's time column)")
    if args.json:
        conv.emit_json({"calibration": str(args.calibration), "model": cal.model.name,
                        "version": cal.version, "effects": effects,
                        **({"effects_state_start": start} if cal.version > 1 else {}),
                        "rest": {"mode": args.rest, "runs": [r.to_dict() for r in reports]},
                        **({"zero": {"config": zero.to_dict(), "runs": zeros}} if zero else {}),
                        "scores": [s.to_dict() for s in scores]}, args.json)
    else:
        print(f"calibration {args.calibration}: model {cal.model.name}")
        if cal.version > 1:
            print("effects: " + "; ".join(f"{a}: {', '.join(e) or 'none'}"
                                          for a, e in effects.items()) + f"; from {start}")
        for z in zeros:
            print(f"boot-time zero, {z['run']}: {z['status']}" + (
                f" at {z['done_s']:g} s, " + ", ".join(
                    f"{a} {v:+.5f}" for a, v in z["offset_dps"].items()) + " °/s"
                if z["status"] == "done" else f" ({z['windows_rejected']} windows refused)"))
        print(score_table(scores))
    if args.report:
        _report(args, cal, feats, title=f"evaluate: {args.calibration}",
                calibration_path=str(args.calibration), zero=zero)
    return 0


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    sim = sub.add_parser("sim", help="simulate the chamber experiment or a gyro on a CAN bus")
    sim_sub = sim.add_subparsers(dest="sim_command", required=True)
    ch = sim_sub.add_parser("chamber", help="simulate chamber heating runs into run files")
    ch.add_argument("--heating-min", type=float, nargs="+", default=None,
                    help="heating times, min (default: the paper's 5 10 20 30 40 50 60)")
    ch.add_argument("--out", required=True, metavar="DIR",
                    help="DIRECTORY for the run files, one per run (created with its parents)")
    ch.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ch.add_argument("--rate-hz", type=float, default=10.0, help="sample rate, Hz (default 10)")
    ch.add_argument("--hold-s", type=float, default=3600.0,
                    help="hold before and after the ramp, s (default 3600)")
    ch.add_argument("--validation", action="store_true",
                    help="name runs valid-… and draw seeds apart from fitting runs")
    conv.add_json_option(ch, what="the files written (path, rows, duration_s)")
    ch.add_argument("--profile", choices=PROFILE_NAMES, default="default",
                    help="simulator profile: default, or tested against measurements "
                    "(tang2013, bmi270: what beat its null tests; docs/findings.md §7)")
    ch.set_defaults(func=cmd_sim_chamber)
    from gyrotherm.cli import _simlife
    from gyrotherm.cli import _stream as _stream_cli

    _stream_cli.register(sim_sub)
    _simlife.register(sim_sub)

    f = sub.add_parser("fit", help="fit a bias model to run files and write a calibration")
    f.add_argument("runs", nargs="+", help="run files, delimited text, candump logs, flight logs "
                   "(see the input options)")
    f.add_argument("--model", choices=sorted(MODELS), default="paper",
                   help="bias model: paper (T, ΔT), t2/t3 (temperature-only polynomials)")
    f.add_argument("--method", choices=("auto", *METHODS), default="auto",
                   help="offsets: least squares over all runs on 1-s blocks, one switch-on "
                   "offset per run, the intercept their mean (what 'diagnose --calibration' "
                   "fits); pooled: over all rows, one intercept; paper-average (eq. 12: mean "
                   "of per-run fits); auto (default): offsets when at least half of the "
                   "temperature variance is within runs (warm-ups, ramps), else pooled "
                   "(isothermal plateaus)")
    f.add_argument("--out", required=True, metavar="FILE",
                   help="calibration FILE to write (JSON; parent directories created; "
                   "never over a run file)")
    f.add_argument("--no-validation", action="store_true",
                   help="skip the leave-one-run-out validation")
    f.add_argument("--pool-vehicles", action="store_true",
                   help="fit one device name's runs together even when the logs name "
                   "several vehicles (default: refused; one calibration is one IMU)")
    f.add_argument("--effects", metavar="A,B",
                   help="also fit these effects with the paper model (thermal_lag, "
                   "hysteresis, warmup, cubic, gradient_quadratic, drift), per axis, time "
                   "constants and hysteresis transition searched as 'diagnose' does "
                   "(≥ 2 runs; writes a version-2 calibration; default: none)")
    conv.add_json_option(f, what="the rest report, the calibrations written, their "
                         "coefficients and leave-one-run-out scores")
    f.add_argument("--report", metavar="DIR",
                   help="also write per-axis figures and report.md to DIR (default: none)")
    _fitgates.add_force_option(f)
    add_estimator_options(f, auto=True)
    add_input_options(f)
    _fitrest.add_rest_options(f)
    _pool.add_worker_options(f)
    f.set_defaults(func=cmd_fit)

    e = sub.add_parser("evaluate", help="score a calibration on run files (Table 2 style)")
    e.add_argument("calibration", help="calibration file (JSON)")
    e.add_argument("runs", nargs="+", help="run files, delimited text, candump logs, flight logs "
                   "(see the input options)")
    conv.add_json_option(e, what="the scores")
    e.add_argument("--report", metavar="DIR",
                   help="also write per-axis figures and report.md to DIR (default: none)")
    add_input_options(e)
    _fitrest.add_rest_options(e, use="score")
    add_zero_option(e)
    e.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("paper", help="reproduce Tables 1 and 2 on simulated chamber runs")
    p.add_argument("--seed", type=int, default=1, help="random seed")
    p.add_argument("--rate-hz", type=float, default=10.0, help="sample rate, Hz")
    p.add_argument("--axis", choices=("x", "y", "z"), default="x", help="axis of Table 1")
    p.add_argument("--out", metavar="DIR",
                   help="also write the simulated runs to this DIRECTORY (created; "
                   "default: not written)")
    conv.add_json_option(p, what="Tables 1 and 2")
    p.add_argument("--profile", choices=PROFILE_NAMES, default="default",
                   help="simulator profile (default, tang2013, bmi270; docs/findings.md §7)")
    p.set_defaults(func=_paper.cmd_paper)
