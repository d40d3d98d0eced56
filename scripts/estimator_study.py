"""Which estimator settings matter, chosen by held-out deployed error (issue 19, item 4).

    .venv/bin/python scripts/estimator_study.py [--seeds 7101 ...] [--json OUT]

The calibration and the vehicle run the same causal T/ΔT estimator with the settings the
calibration stores (``EstimatorConfig``; its online/offline parity is tested in
``tests/estimators``): what a setting changes is the features the calibration is fitted
on *and* the features it is applied to. So each candidate setting is scored the way the
vehicle would see it: fit on 4 runs of a device of the independent generator
(:func:`~gyrotherm.analysis.synth._synth.synth_runs`, 6000 s at 10 Hz), apply the
calibration to the 5th run through the same estimator, and take the RMS of (bias removed −
the generator's true bias), the run's mean error removed (its switch-on offset: the
boot-time zero measures it, no calibration can know it).

Grid, fixed before any result was seen: readout refresh {0.1, 0.32, 0.64, 1.28} s × LSB
{0.0625, 0.25, 1.0} °C (sensor noise 0.02 °C, the generator's), two truths — the paper
model alone (``null``) and with a ΔT² effect (``gradient_quadratic``, deployed as the
diagnosis would: paper + ΔT² fitted on the estimator's features) — and seeds 7101–7105.
Settings, one factor at a time around the rule `diagnose` used before this study
(:func:`~gyrotherm.analysis._prep.estimator_for` at bedb887: fed once per max(refresh,
1 s), noise = characterised − LSB/√6, q = 1e-7 °C²/s³):

* ``slot``: ``1s`` (the old rule), ``refresh`` (every new reading: the refresh period
  :func:`characterise` measures), ``row`` (every row: 0);
* ``noise``: ``rule`` (the old one) or ``white`` (the white noise :func:`characterise`
  measures about a smooth fit, the LSB passed separately as ``quantisation_c``);
* ``q``: 1e-8, 1e-7, 1e-6 °C²/s³;
* ``tau``: 120 s or 30 s (ΔT = τ·dT/dt: a pure scale, absorbed by the paper model's
  ΔT coefficients; checked, not assumed).

Prints per setting the median (min–max) over cells and seeds of the held-out error and its
ratio to the old rule's in the same cell; ``--json`` writes every number.

**Selection, then confirmation.** The run on seeds 7101–7105 (e634049) selected the rule:
τ changes nothing (to the last digit), q = 1e-7 beats 1e-8 and 1e-6, feeding every new
reading and the white-noise estimate each beat the old rule in most cells. Their combination
(``--settings both``) was then scored on the same selection seeds: worse than feeding every
reading alone where the LSB is coarse and the refresh fast (1 °C at 0.1–0.32 s: ×1.10–1.32
of the old rule, against ×0.99–1.13), so it was dropped (its confirmation run was stopped
unread). The rule kept (``--settings new``: slot=refresh, noise as before) is scored once on
confirmation seeds 7201–7205 (:data:`CONFIRM_SEEDS`, written before that run;
``--seeds confirm``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis._prep import characterise
from gyrotherm.analysis._to_calibration import fit_effects
from gyrotherm.analysis.synth._synth import synth_runs
from gyrotherm.codecs import Run
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.estimators import EstimatorConfig

SEEDS = (7101, 7102, 7103, 7104, 7105)
CONFIRM_SEEDS = (7201, 7202, 7203, 7204, 7205)
REFRESH_S = (0.1, 0.32, 0.64, 1.28)
LSB_C = (0.0625, 0.25, 1.0)
TRUTHS = ("null", "gradient_quadratic")
SETTINGS: dict[str, dict[str, object]] = {
    "old rule": {},
    "slot=refresh": {"slot": "refresh"},
    "slot=row": {"slot": "row"},
    "noise=white": {"noise": "white"},
    "q=1e-8": {"q": 1e-8},
    "q=1e-6": {"q": 1e-6},
    "tau=30": {"tau": 30.0},
}
NEW: dict[str, dict[str, object]] = {"old rule": {}, "new rule": {"slot": "refresh"}}
BOTH: dict[str, dict[str, object]] = {
    "old rule": {}, "slot=refresh, noise=white": {"slot": "refresh", "noise": "white"}}


def estimator(runs: Sequence[Run], slot: str = "1s", noise: str = "rule", q: float = 1e-7,
              tau: float = 120.0) -> EstimatorConfig:
    """The estimator a setting gives on ``runs`` (module docstring)."""
    ro = [characterise(r, "x") for r in runs]
    refresh = float(np.median([r.refresh_period_s or r.period_s for r in ro]))
    lsb = float(np.median([r.lsb_c for r in ro]))
    period = {"1s": max(refresh, 1.0), "refresh": refresh, "row": 0.0}[slot]
    if noise == "rule":
        n = float(np.median([r.noise_c for r in ro]))
        sigma = max(n - lsb / np.sqrt(6), 0.005) if lsb > 0 else n
    else:
        sigma = max(float(np.median([r.white_noise_c for r in ro])), 0.005)
    return EstimatorConfig(tau_s=tau, noise_c=sigma, quantisation_c=max(lsb, 1e-4),
                           process_noise_c2_per_s3=q, update_period_s=period)


def held_out_error(cal: Calibration, run: Run) -> float:
    """RMS of (bias removed − true bias) on ``run`` through the calibration's estimator,
    the run's mean error removed, rows where the estimator has settled (t ≥ 60 s)."""
    f = features(run, cal.estimator)
    b = cal.bias_series("x", f.temperature_c, f.delta_t_c, f.time_s)[0]
    e = (b - run.true_bias_dps["x"])[f.time_s - f.time_s[0] >= 60.0]
    return float(np.sqrt(np.mean((e - e.mean()) ** 2)))


def one(truth: str, refresh_s: float, lsb_c: float, seed: int,
        settings: dict[str, dict[str, object]] = SETTINGS) -> dict[str, float]:
    effects = {} if truth == "null" else {"gradient_quadratic": {}}
    cfg = SynthConfig(duration_s=6000.0, readout_period_s=refresh_s, readout_lsb_c=lsb_c,
                      effects=effects)
    runs, _ = synth_runs(cfg, n_runs=5, seed=seed)
    train, held = runs[:4], runs[4]
    out: dict[str, float] = {}
    for name, kw in settings.items():
        est = estimator(train, **kw)  # type: ignore[arg-type]
        feats = [features(r, est) for r in train]
        if truth == "null":
            cal = fit(feats, "paper", estimator=est)
        else:
            cal = fit_effects(feats, {"x": ("gradient_quadratic",)}, estimator=est).calibration
        out[name] = held_out_error(cal, held)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", nargs="+", default=["select"],
                   help="'select' (7101–7105), 'confirm' (7201–7205) or seed numbers")
    p.add_argument("--settings", choices=("one-at-a-time", "both", "new"),
                   default="one-at-a-time")
    p.add_argument("--json", help="write every figure here")
    a = p.parse_args(argv)
    named = {"select": list(SEEDS), "confirm": list(CONFIRM_SEEDS)}
    a.seeds = [s for x in a.seeds for s in (named[x] if x in named else [int(x)])]
    settings = {"one-at-a-time": SETTINGS, "both": BOTH, "new": NEW}[a.settings]
    cells: list[dict[str, object]] = []
    for truth in TRUTHS:
        for refresh in REFRESH_S:
            for lsb in LSB_C:
                for seed in a.seeds:
                    err = one(truth, refresh, lsb, seed, settings)
                    cells.append({"truth": truth, "refresh_s": refresh, "lsb_c": lsb,
                                  "seed": seed, "error_dps": err})
                    print(f"estimator_study: {truth} refresh {refresh} s LSB {lsb} °C seed "
                          f"{seed}: " + ", ".join(f"{k} {v:.4f}" for k, v in err.items()),
                          file=sys.stderr, flush=True)
    print("held-out bias error (°/s RMS, offset removed) and its ratio to the old rule in "
          f"the same cell, median (min–max) over {len(REFRESH_S) * len(LSB_C)} readouts × "
          f"{len(a.seeds)} seeds:\n")
    print("| truth | setting | error °/s | ÷ old rule | cells better / worse by > 3 % |")
    print("|---|---|---|---|---|")
    for truth in TRUTHS:
        rows = [c for c in cells if c["truth"] == truth]
        for name in settings:
            err = [float(c["error_dps"][name]) for c in rows]  # type: ignore[index]
            ratio = [float(c["error_dps"][name]) / float(c["error_dps"]["old rule"])  # type: ignore[index]
                     for c in rows]
            better = sum(r < 0.97 for r in ratio)
            worse = sum(r > 1.03 for r in ratio)
            print(f"| {truth} | {name} | {statistics.median(err):.4f} ({min(err):.4f}–"
                  f"{max(err):.4f}) | {statistics.median(ratio):.3f} ({min(ratio):.3f}–"
                  f"{max(ratio):.3f}) | {better} / {worse} of {len(rows)} |")
    if a.json:
        Path(a.json).write_text(json.dumps(cells, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
