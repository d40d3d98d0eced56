"""``gyrotherm diagnose RUNS... [--json [FILE]] [--report DIR] [--axis x|y|z]
[--calibration CAL]``."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import _fitrest, _pool, _prep
from gyrotherm.cli._common import load_runs
from gyrotherm.cli._inputs import add_input_options
from gyrotherm.codecs import Run
from gyrotherm.readers import InputSpec


def load(paths: Sequence[str], *, quiet: bool = False,
         spec: InputSpec | None = None) -> list[Run]:
    """Run files (CSV version 1) and ``candump -l`` logs (told apart by content,
    see :func:`gyrotherm.cli._common.load_run`); run names must be unique."""
    return unique_names(load_runs(paths, quiet=quiet, spec=spec))


def unique_names(runs: list[Run]) -> list[Run]:
    """``runs``, refused (RunFileError) when two share a name."""
    names = [r.name for r in runs]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise RunFileError(
            f"runs share a name {dupes}: give each run file its own '# name:' "
            "(a candump log is named after its file)")
    return runs


def candump_notes(runs: Sequence[Run]) -> list[str]:
    """One line per run read from a candump log that lost frames or rows (from the
    counts :func:`~gyrotherm.codecs._candump_run.run_from_candump` keeps in metadata)."""
    notes = []
    for r in runs:
        md = r.metadata
        if md.get("source_format") != "candump":
            continue
        lost = {k.removeprefix("frames_rejected_"): int(v) for k, v in md.items()
                if k.startswith("frames_rejected_") and int(v)}
        for key in ("counter_jumps", "rows_before_first_temperature"):
            if int(md.get(key, "0")):
                lost[key] = int(md[key])
        if lost:
            listing = ", ".join(f"{k}: {v}" for k, v in lost.items())
            notes.append(f"{r.name}: candump log {r.source} ({md.get('frames')} frames): "
                         f"{listing}")
    return notes


def _one_imu(runs: Sequence[Run]) -> None:
    """The diagnosis models one gyro: runs of several IMUs or vehicles are refused."""
    for key, what in (("device_id", "IMUs"), ("vehicle_id", "vehicles")):
        named = {str(r.metadata.get(key, "") or "") for r in runs} - {""}
        if len(named) > 1:
            raise ConfigError(f"diagnose models one gyro; these runs are of {len(named)} "
                              f"{what} ({', '.join(sorted(named))}): give one's runs "
                              "(--device ID selects an IMU)")


def cmd_diagnose(args: argparse.Namespace) -> int:
    from gyrotherm.analysis import diagnose, write_report  # matplotlib, scipy: here only

    quiet = bool(getattr(args, "quiet", False))
    if args.margin <= 0 or args.margin >= 1:
        raise ConfigError(f"--margin = {args.margin!r} is outside (0, 1)")
    conv.check_runs(args.runs, command="diagnose")
    conv.check_json_target(args.json)
    loaded = _prep.load(args, _prep.prep_from_args(args))  # read + rest on the workers
    runs = unique_names(loaded.runs)
    _one_imu(runs)
    _fitrest.refuse_motion(loaded.reports, command="diagnose")
    start = time.perf_counter()

    def say(msg: str) -> None:
        if not quiet:
            print(f"diagnose: {msg}", file=sys.stderr, flush=True)

    result = diagnose(runs, axis=args.axis, margin=args.margin, seed=args.seed,
                      simulate=not args.no_simulation, progress=say)
    data = result.to_dict()
    lost = candump_notes(runs)
    for line in lost:
        say(line)
    data["notes"] = [*data["notes"], *lost]
    data["elapsed_s"] = round(time.perf_counter() - start, 3)
    out = conv.emit_json(data, args.json) if args.json else None
    if out is not None:
        say(f"wrote {out}")
    if args.report:
        md = write_report(result, conv.output_dir(args.report, option="--report"))
        say(f"wrote {md}")
    if args.calibration:
        _write_calibration(args, runs, result, say)
    if not quiet:
        print(f"diagnose: found {_found(result)}; extended {result.extended.name}: held-out RMS "
              f"{result.baseline_heldout_rms_dps:.4g} → {result.extended_heldout_rms_dps:.4g} °/s "
              f"(gain {result.gain:.2f})", file=sys.stderr)
        if result.floors:  # what it could not have seen (analysis/_floor.py)
            floors = ", ".join(f"×{f.gain:.2f} in {f.variable}" for f in result.floors)
            print(f"diagnose: not resolvable at this readout: a structure gaining less than "
                  f"{floors} (held out, over {result.extended.name})", file=sys.stderr)
    return loaded.exit_status  # 2 when a log failed (diagnosed on the others)


def _found(result: Any) -> str:
    """The summary's list: each finding and each unexplained structure with its gain and
    what the diagnosis says of it (its shape; the effects or variables it is not told apart
    from)."""
    shape_unresolved = {v.effect.removeprefix("shape:") for v in result.not_resolvable
                        if v.effect.startswith("shape:")}
    items = []
    for f in result.findings:
        said = [f"gain {f.gain:.2f}"]
        if f.shape:
            said.append("its shape differs")
        if f.effect in shape_unresolved:
            said.append("its shape is not resolvable at this readout")
        if f.rivals:
            said.append(f"not told apart from {f.rivals}")
        items.append(f"{f.effect} ({'; '.join(said)})")
    for u in result.unexplained:
        said = [f"gain {u.gain:.2f}"] + ([f"not told apart from {u.alike}"] if u.alike else [])
        items.append(f"unexplained in {u.variable} ({'; '.join(said)})")
    return ", ".join(items) or "nothing"


def _write_calibration(args: argparse.Namespace, runs: Sequence[Run], result: Any,
                       say: Callable[[str], None]) -> None:
    """``--calibration``: the chosen extended model, selected per axis (every axis the
    runs share), refitted on the stored estimator's features."""
    from gyrotherm.analysis._diagnose import export_calibration

    fitted = export_calibration(runs, result, margin=args.margin, progress=say)
    cal = fitted.calibration
    path = cal.save(conv.output_path(args.calibration, option="--calibration"))
    for axis in cal.axes:
        say(f"calibration axis {axis}: paper{''.join('+' + e for e in cal.effect_names(axis))}"
            f", leave-one-run-out RMS {fitted.baseline_heldout_rms_dps[axis]:.4g} → "
            f"{fitted.heldout_rms_dps[axis]:.4g} °/s")
    say(f"wrote {path} (calibration version {cal.version}, axes {','.join(cal.axes)})")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+",
                   help="run files, delimited text, candump -l logs, flight logs (see the "
                   "input options), ≥ 2 runs, one device")
    conv.add_json_option(p, what="the diagnosis (schema gyrotherm.diagnosis/1)")
    p.add_argument("--report", metavar="DIR",
                   help="also write report.md and PNG plots to DIR (created; default: none)")
    p.add_argument("--axis", choices=("x", "y", "z"),
                   help="rate axis (default: the first rate column present)")
    p.add_argument("--margin", type=float, default=0.10,
                   help="relative held-out RMS improvement an effect must buy (default 0.10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulator replay (default 0)")
    p.add_argument("--no-simulation", action="store_true",
                   help="skip the simulator calibration and replay")
    p.add_argument("--calibration", metavar="CAL.json",
                   help="(default: none) also write a calibration FILE of the chosen "
                   "extended model for EVERY "
                   "axis the runs share: --axis gets the diagnosis' effects, each other "
                   "axis its own selection (paper model where nothing is found); "
                   "coefficients refitted on the stored estimator's output")
    add_input_options(p)
    _pool.add_worker_options(p)
    _fitrest.add_rest_options(p, auto="auto: refuse runs in which rest detection finds "
                              "motion (the diagnosis needs whole runs at rest)")
    p.set_defaults(func=cmd_diagnose)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("diagnose", help="which physical effect do the model and simulator miss?",
                       description="Fit the paper model, compare measured and simulated "
                       "output, test candidate effects leave-one-run-out.")
    add_arguments(p)
