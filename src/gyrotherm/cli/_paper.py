"""``gyrotherm paper``: Tang et al.'s Tables 1 and 2 on simulated chamber runs (also
the first part of ``gyrotherm demo``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrotherm.cli import _conventions as conv
from gyrotherm.cli._common import progress
from gyrotherm.cli._tables import coefficient_table, error_table
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import (
    Calibration,
    default_scaling,
    features,
    fit,
    fit_per_run,
    score,
)
from gyrotherm.estimators import EstimatorConfig


def cmd_paper(args: argparse.Namespace) -> int:
    """Simulate the paper's experiment, fit, and print Table 1- and Table 2-style results."""
    paper_tables(args)
    return 0


def paper_tables(args: argparse.Namespace) -> tuple[Run, Calibration]:
    """Print the paper's tables (see :func:`cmd_paper`); return the validation run and
    the eq. 12 (paper-average) calibration fitted on the heating runs."""
    from gyrotherm.sim import PAPER_HEATING_MIN, chamber_runs
    from gyrotherm.sim._profiles import get_profile

    profile = get_profile(getattr(args, "profile", "default"))
    gyro, chamber = profile.gyro, profile.chamber
    est = EstimatorConfig(tau_s=gyro.tau_s)
    quiet = args.quiet
    runs = chamber_runs(PAPER_HEATING_MIN, seed=args.seed, rate_hz=args.rate_hz,
                        gyro=gyro, chamber=chamber,
                        progress=progress("simulating heating runs", quiet=quiet))
    valid = chamber_runs([60], seed=args.seed, rate_hz=args.rate_hz, validation=True,
                         gyro=gyro, chamber=chamber)[0]
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        for r in [*runs, valid]:
            write_run(r, out / f"{r.name}.csv")
    report = progress("estimating T and ΔT", quiet=quiet)
    feats = []
    for i, r in enumerate([*runs, valid]):
        feats.append(features(r, est))
        report(i + 1, len(runs) + 1)
    train, vfeat = feats[:-1], feats[-1]
    scaling = default_scaling(train)
    per_run = fit_per_run(train, "paper", estimator=est, scaling=scaling)
    avg = fit(train, "paper", estimator=est, method="paper-average", scaling=scaling)
    pooled = fit(train, "paper", estimator=est, method="pooled", scaling=scaling)
    axis = args.axis
    rows = [(f"{m:g} min", c) for m, c in zip(PAPER_HEATING_MIN, per_run, strict=True)]
    rows += [("mean (eq. 12)", avg), ("pooled", pooled)]
    as_json = getattr(args, "json", None)
    if not as_json:
        print(coefficient_table(rows, axis, truth=dict(gyro.bias.coefficients[axis]),
                                title=f"Table 1 — paper model per heating run, axis {axis} "
                                "(bias °/s; T, ΔT °C; truth = the simulator's coefficients)"))
    columns = []
    for i in (0, 5, 6):
        t2 = fit([train[i]], "t2", estimator=est, scaling=scaling)
        columns.append((f"t2 {PAPER_HEATING_MIN[i]:g} min", score(t2, vfeat)))
    columns.append(("t3 pooled", score(fit(train, "t3", estimator=est, scaling=scaling), vfeat)))
    columns.append(("paper (eq.12)", score(avg, vfeat)))
    columns.append(("paper pooled", score(pooled, vfeat)))
    if as_json:
        conv.emit_json({
            "table1": {"axis": axis, "units": "bias °/s; T, ΔT °C",
                       "rows": {name: c.physical_coefficients(axis) for name, c in rows},
                       "truth": dict(gyro.bias.coefficients[axis])},
            "table2": {"run": valid.name,
                       "columns": {name: [s.to_dict() for s in sc] for name, sc in columns}},
        }, as_json)
        return valid, avg
    print()
    print(error_table(columns, title="Table 2 — validation run (60 min heating), "
                      "errors after compensation, mean over axes x, y, z"))
    return valid, avg
