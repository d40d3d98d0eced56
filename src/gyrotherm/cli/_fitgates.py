"""``gyrotherm fit``: the quality gates (:mod:`gyrotherm.compensation._quality`) per
device, before any calibration is written; ``--force`` to write one anyway."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation import Calibration, RunFeatures
from gyrotherm.compensation._models import get_model
from gyrotherm.compensation._quality import Gate, check


def add_force_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true",
                        help="write the calibration even when a quality gate refuses it "
                        "(too few rows, narrow or stuck temperature, ill-conditioned "
                        "model; docs/inputs.md); the failures are recorded in its "
                        "provenance (quality_warnings)")


def gate(args: argparse.Namespace, feats: Sequence[RunFeatures], device: str) -> list[Gate]:
    """The gates of one device's runs, printed (stderr with ``--json``); a
    CalibrationError naming every refusing gate unless ``--force``."""
    gates = check(feats, get_model(args.model), validation=not args.no_validation)
    failed = [g for g in gates if not g.passed]
    refusing = [g for g in failed if g.refuses]
    sources = ", ".join(sorted({f.source for f in feats}))
    who = f"device {device!r} of {sources}" if device else sources
    if refusing and not args.force:
        raise CalibrationError(
            f"{who}: no calibration written, refused by quality gate"
            f"{'s' if len(refusing) > 1 else ''} " + "; ".join(g.line() for g in refusing)
            + ". Pass --force to write it anyway (the failures are recorded in its provenance)")
    out = sys.stderr if args.json else sys.stdout
    for g in failed:
        print(f"quality warning, {who}: {g.line()}", file=out)
    return gates


def record(cal: Calibration, gates: Sequence[Gate]) -> Calibration:
    """``cal`` with the gates in its provenance: ``quality`` (every gate) and
    ``quality_warnings`` (the failed ones, one line each)."""
    failed = [g.line() for g in gates if not g.passed]
    extra: dict[str, Any] = {"quality": [g.to_dict() for g in gates]}
    if failed:
        extra["quality_warnings"] = failed
    return replace(cal, provenance={**cal.provenance, **extra})


__all__ = ["add_force_option", "gate", "record"]
