"""``gyrotherm diagnose RUNS... --json OUT [--report DIR] [--axis x|y|z]``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.analysis import diagnose, write_report
from gyrotherm.cli._common import progress
from gyrotherm.codecs import Run, read_run


def _looks_like_candump(path: Path) -> bool:
    try:
        with path.open("rb") as fh:
            head = fh.read(64).lstrip()
    except OSError:
        return False
    return head.startswith(b"(") or path.suffix == ".log"


def load(paths: Sequence[str], *, quiet: bool = False) -> list[Run]:
    """Read run files (CSV version 1); a candump log is named as such in the error."""
    report = progress("reading runs", quiet=quiet)
    runs = []
    for i, name in enumerate(paths):
        path = Path(name)
        if _looks_like_candump(path):
            raise RunFileError(
                f"{path}: looks like a candump log; this gyrotherm diagnoses run files "
                "(CSV version 1): convert the log to a run file first"
            )
        runs.append(read_run(path))
        report(i + 1, len(paths))
    names = [r.name for r in runs]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise RunFileError(f"runs share a name {dupes}: give each run file its own '# name:'")
    return runs


def cmd_diagnose(args: argparse.Namespace) -> int:
    quiet = bool(getattr(args, "quiet", False))
    if args.margin <= 0 or args.margin >= 1:
        raise ConfigError(f"--margin = {args.margin!r} is outside (0, 1)")
    runs = load(args.runs, quiet=quiet)
    start = time.perf_counter()

    def say(msg: str) -> None:
        if not quiet:
            print(f"diagnose: {msg}", file=sys.stderr, flush=True)

    result = diagnose(runs, axis=args.axis, margin=args.margin, seed=args.seed,
                      simulate=not args.no_simulation, progress=say)
    data = result.to_dict()
    data["elapsed_s"] = round(time.perf_counter() - start, 3)
    out = Path(args.json)
    if str(out) == "-":
        json.dump(data, sys.stdout, indent=2)
        print()
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
        say(f"wrote {out}")
    if args.report:
        md = write_report(result, args.report)
        say(f"wrote {md}")
    if not quiet:
        found = ", ".join(f"{f.effect} (gain {f.gain:.2f})" for f in result.findings) or "nothing"
        print(f"diagnose: found {found}; extended {result.extended.name}: held-out RMS "
              f"{result.baseline_heldout_rms_dps:.4g} → {result.extended_heldout_rms_dps:.4g} °/s "
              f"(gain {result.gain:.2f})", file=sys.stderr)
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("runs", nargs="+", help="run files (CSV version 1), ≥ 2, one device")
    p.add_argument("--json", required=True,
                   help="write the diagnosis (schema gyrotherm.diagnosis/1) here; '-' = stdout")
    p.add_argument("--report", metavar="DIR", help="also write report.md and PNG plots to DIR")
    p.add_argument("--axis", choices=("x", "y", "z"),
                   help="rate axis (default: the first rate column present)")
    p.add_argument("--margin", type=float, default=0.10,
                   help="relative held-out RMS improvement an effect must buy (default 0.10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulator replay (default 0)")
    p.add_argument("--no-simulation", action="store_true",
                   help="skip the simulator calibration and replay")
    p.set_defaults(func=cmd_diagnose)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("diagnose", help="which physical effect do the model and simulator miss?",
                       description="Fit the paper model, compare measured and simulated "
                       "output, test candidate effects leave-one-run-out.")
    add_arguments(p)
