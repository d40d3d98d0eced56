"""fit and diagnose --calibration on nothing to find (issue 19, item 4).

    .venv/bin/python scripts/null_bound.py [--seeds S ...] [--json OUT]

Issue 19, item 4: "With nothing to find, the calibration ``diagnose --calibration``
writes is never worse than ``fit``'s by more than 3 % on held-out streamed runs, across
the readout sweep." Since 4443ce3 (and 5864955) ``gyrotherm fit`` chooses its estimator
from the runs' readout as ``diagnose --calibration`` does and fits the paper model with
one offset per run on 1-s blocks (``--method auto``), so when the diagnosis names
nothing the two files are the same calibration; they can differ only where the
diagnosis names something on null data (a false alarm). This script measures how much
that costs on the vehicle.

Per readout cell (refresh {0.1, 0.32, 0.64, 1.28} s × LSB {0.0625, 0.25, 1.0} °C, the
grid of ``scripts/estimator_study.py``, sensor noise the generator's 0.02 °C) and seed:

1. the independent generator (:func:`gyrotherm.analysis.synth._synth.synth_runs`,
   nothing injected, 6000 s at 10 Hz: ``deployed_gain.FULL``): 4 training runs and 1
   held-out run of the same device;
2. the training runs written as CSV (:func:`gyrotherm.codecs.write_run`) to a temporary
   directory, and the **real commands** run on them: ``gyrotherm -q fit RUNS --out F
   --no-validation`` (estimator and ``--method auto`` chosen by the command; the
   validation only scores, it does not change the file) and ``gyrotherm -q diagnose RUNS
   --calibration D --no-simulation``; the two files loaded
   (:func:`gyrotherm.compensation.load_calibration`) are the calibrations scored;
3. beside them, the same two calibrations by the API on the in-memory runs (``fit``'s:
   ``estimator_of([run_readout(r) ...])``, ``features``, ``choose_method``, ``fit(...,
   "paper", estimator=..., method=...)``; ``diagnose``'s: :func:`diagnose` with
   ``simulate=False``, then :func:`export_calibration`): the diagnosis' findings and
   unexplained structures are taken from here (what it "named"), and the largest
   relative coefficient difference between API and CLI is recorded (the CSV round trip
   rounds the rows, so they agree closely, not exactly);
4. both CLI calibrations streamed over the held-out run's CAN frames through the
   daemon's real :class:`gyrotherm.daemon.Pipeline` (``deployed_gain.stream``) and
   scored as ``deployed_gain.score`` does: bias removed − the generator's
   ``true_bias_dps`` (axis x) on the rows not flagged ``ESTIMATOR_WARMUP``, the error's
   mean removed (the held-out switch-on offset: the boot-time zero's job);
5. ratio = RMS(diagnose's) / RMS(fit's) (:func:`ratio`); **identical** (:func:`identical`):
   same model, estimator and scaling, coefficients equal to rtol 1e-9 (atol 1e-12),
   and no effects in either.

Criterion: ratio ≤ :data:`TOLERANCE` (1.03) for every (cell, seed).

**Seeds** (:data:`SEEDS`, 9301–9305) were fixed in this docstring and committed before
any of them was run through this script; no script, test or document used them before
(grep of scripts/, tests/, docs/, src/). Seed 23 was used to time one cell, and is not
in the list. The run of record is run once and every cell is reported.

**Cost** (timed on one cell, seed 23): generator ≈ 1.2 s, API fit 0.4 s and diagnosis
1.8 s, CSV writing 0.7 s, the fit command 1.8 s, the diagnose command 2.3 s, two streams
≈ 2 s each: ≈ 12 s per (cell, seed), ≈ 12 min for 12 cells × 5 seeds; the run of
record took 653 s (docs/findings.md §6).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._diagnose import export_calibration
from gyrotherm.analysis._readout_estimator import estimator_of, run_readout
from gyrotherm.analysis.synth._synth import synth_runs
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.cli import main as cli_main
from gyrotherm.codecs import FrameEncoder, Run, write_run
from gyrotherm.compensation import Calibration, features, fit, load_calibration
from gyrotherm.compensation._fit_offsets import choose_method
from gyrotherm.sim import frames_from_run

sys.path.insert(0, str(Path(__file__).resolve().parent))  # scripts/ is not a package
import deployed_gain as dg
from estimator_study import LSB_C, REFRESH_S

#: Evaluation seeds, one device per readout cell and seed; fixed (and committed) before
#: any was run (module docstring). Not to be tuned to make a cell pass.
SEEDS = (9301, 9302, 9303, 9304, 9305)
TOLERANCE = dg.NONE_TOLERANCE  # issue: diagnose's ≤ 1.03 × fit's with nothing to find
CALIBRATIONS = ("fit", "diagnose")
_OFF = "rms_offset_removed"


def identical(a: Calibration, b: Calibration, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
    """The same paper calibration: model, estimator, scaling and axes equal, every
    coefficient equal to ``rtol`` (``atol`` near zero), and no effects in either."""
    if a.model.name != b.model.name or a.estimator != b.estimator or a.scaling != b.scaling:
        return False
    if a.axes != b.axes or any(a.effect_names(x) or b.effect_names(x) for x in a.axes):
        return False
    return all(np.allclose(a.coefficients[x], b.coefficients[x], rtol=rtol, atol=atol)
               for x in a.axes)


def max_rel_diff(a: Calibration, b: Calibration) -> float:
    """Largest |a − b| / max(|a|, |b|) over the coefficients of the axes both have."""
    out = 0.0
    for x in set(a.axes) & set(b.axes):
        p, q = np.asarray(a.coefficients[x]), np.asarray(b.coefficients[x])
        den = np.maximum(np.maximum(np.abs(p), np.abs(q)), 1e-300)
        out = max(out, float(np.max(np.abs(p - q) / den)))
    return out


def ratio(scores: Mapping[str, Mapping[str, float]], key: str = _OFF) -> float:
    """RMS(diagnose's) / RMS(fit's) of one ``deployed_gain.score``."""
    return float(scores["diagnose"][key]) / float(scores["fit"][key])


def named(cal: Calibration) -> list[str]:
    """The effects ``cal`` carries, ``axis:name``."""
    return [f"{x}:{n}" for x in cal.axes for n in cal.effect_names(x)]


def _quiet_main(argv: Sequence[str]) -> None:
    """``gyrotherm ARGV``, its stdout and stderr kept out of the study's output."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        rc = cli_main(list(argv))
    if rc != 0:
        raise RuntimeError(f"gyrotherm {' '.join(argv)}: exit {rc}\n{buf.getvalue()[-2000:]}")


def one_cell(refresh_s: float, lsb_c: float, seed: int,
             s: dg.Settings = dg.FULL) -> dict[str, Any]:
    """Everything for one (readout cell, seed): module docstring, steps 1–5."""
    cfg = SynthConfig(duration_s=s.duration_s, rate_hz=s.rate_hz, readout_period_s=refresh_s,
                      readout_lsb_c=lsb_c, effects={})
    runs, _ = synth_runs(cfg, n_runs=s.n_train + 1, seed=seed)
    return one_device(runs[:-1], runs[-1], {"refresh_s": refresh_s, "lsb_c": lsb_c,
                                            "seed": seed})


def sweep_null(seed: int) -> dict[str, Any]:
    """A null device of the generalisation sweep's null sets (``--sweep-seeds``): seed j of
    NULL_EVAL_SEEDS / NULL_CONFIRM_SEEDS at its condition CONDITIONS[j % 4], the sweep's
    own runs as training (the generator draws them first: one more run leaves them
    unchanged) and one more run of the device held out."""
    import generalisation_sweep as gs

    for seeds in gs.NULL_SETS:
        if seed in seeds:
            cond = gs.CONDITIONS[seeds.index(seed) % len(gs.CONDITIONS)]
            break
    else:
        raise SystemExit(f"seed {seed} is in no null set of scripts/generalisation_sweep.py")
    cfg = SynthConfig(duration_s=gs.DURATION_S, rate_hz=cond.rate_hz,
                      readout_lsb_c=cond.lsb_c, readout_period_s=cond.period_s)
    runs, _ = variant_runs(cfg, shapes={}, n_runs=cond.n_runs + 1, seed=seed)
    return one_device(runs[:-1], runs[-1], {"refresh_s": cond.period_s, "lsb_c": cond.lsb_c,
                                            "seed": seed, "condition": cond.name})


def one_device(train: Sequence[Run], held: Run, meta: Mapping[str, Any]) -> dict[str, Any]:
    """Steps 2–5 of the module docstring on these training runs and held-out run."""
    start = time.perf_counter()
    # the API
    est = estimator_of([r for r in (run_readout(x) for x in train) if r is not None]).estimator
    feats = [features(r, est) for r in train]
    method, share = choose_method(feats)
    api_fit = fit(feats, "paper", estimator=est, method=method)  # type: ignore[arg-type]
    result = diagnose(train, simulate=False)
    api_diag = export_calibration(train, result).calibration
    # the commands
    with tempfile.TemporaryDirectory(prefix="null_bound-") as tmp:
        d = Path(tmp)
        files = [str(write_run(r, d / f"{r.name}.csv")) for r in train]
        _quiet_main(["-q", "fit", *files, "--out", str(d / "fit.json"), "--no-validation"])
        _quiet_main(["-q", "diagnose", *files, "--calibration", str(d / "diagnose.json"),
                     "--no-simulation"])
        cals = {"fit": load_calibration(d / "fit.json"),
                "diagnose": load_calibration(d / "diagnose.json")}
    frames = list(frames_from_run(held, encoder=FrameEncoder()))
    streamed = {k: dg.stream(held, frames, c, None) for k, c in cals.items()}
    ready = streamed["fit"].ready
    if not np.array_equal(streamed["diagnose"].ready, ready):
        raise RuntimeError(f"{held.name}: other warm-up rows for the two calibrations")
    scores = dg.score({k: v.removed_dps for k, v in streamed.items()},
                      held.true_bias_dps["x"], ready)
    return {
        **meta,
        "method": method, "within_share": share,
        "fit_method_cli": cals["fit"].provenance.get("method"),
        "identical": identical(cals["fit"], cals["diagnose"]),
        "found": sorted(f.effect for f in result.findings),
        "unexplained": [u.variable for u in result.unexplained],
        "effects_cli": named(cals["diagnose"]),
        "effects_api": named(api_diag),
        "api_vs_cli_rel": {"fit": max_rel_diff(api_fit, cals["fit"]),
                           "diagnose": max_rel_diff(api_diag, cals["diagnose"])},
        "rows": int(ready.sum()),
        "scores": scores,
        "ratio": ratio(scores),
        "seconds": time.perf_counter() - start,
    }


def named_text(row: Mapping[str, Any]) -> str:
    """What the diagnosis named (API: findings, unexplained structures) and what the
    diagnose command's file carries."""
    found = [*row["found"], *(f"unexplained {u}" for u in row["unexplained"])]
    return f"named {', '.join(found) or 'nothing'}; file: {', '.join(row['effects_cli']) or '—'}"


def cell_table(rows: Sequence[Mapping[str, Any]], tol: float = TOLERANCE) -> list[str]:
    """Per readout cell: seeds, identical n/N, ratio median and max, seeds over ``tol``."""
    out = ["| refresh s | LSB °C | seeds | identical | ratio median | ratio max | "
           f"ratio > {tol} | fit RMS °/s (median) | named where they differ (seed: names) |",
           "|---|---|---|---|---|---|---|---|---|"]
    cells: dict[tuple[float, float], list[Mapping[str, Any]]] = {}
    for r in rows:
        cells.setdefault((float(r["refresh_s"]), float(r["lsb_c"])), []).append(r)
    for (refresh, lsb), g in cells.items():
        g = sorted(g, key=lambda r: int(r["seed"]))
        ratios = [float(r["ratio"]) for r in g]
        diff = [f"{r['seed']}: {named_text(r)} (×{float(r['ratio']):.3f})"
                for r in g if not r["identical"]]
        fit_rms = statistics.median(float(r["scores"]["fit"][_OFF]) for r in g)
        out.append(f"| {refresh:g} | {lsb:g} | {len(g)} | "
                   f"{sum(bool(r['identical']) for r in g)}/{len(g)} | "
                   f"{statistics.median(ratios):.4f} | {max(ratios):.4f} | "
                   f"{sum(x > tol for x in ratios)} | {fit_rms:.4f} | "
                   f"{'; '.join(diff) or '—'} |")
    return out


def overall(rows: Sequence[Mapping[str, Any]], tol: float = TOLERANCE) -> str:
    """The share of (cell, seed) with ratio ≤ ``tol`` and the worst."""
    ok = sum(float(r["ratio"]) <= tol for r in rows)
    worst = max(rows, key=lambda r: float(r["ratio"]))
    return (f"ratio ≤ {tol}: {ok}/{len(rows)} (cell, seed); identical "
            f"{sum(bool(r['identical']) for r in rows)}/{len(rows)}; worst ×"
            f"{float(worst['ratio']):.4f} (refresh {worst['refresh_s']:g} s, LSB "
            f"{worst['lsb_c']:g} °C, seed {worst['seed']})")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS),
                   help=f"generator seeds (default {' '.join(map(str, SEEDS))}, of record)")
    p.add_argument("--json", metavar="OUT", help="also write every row as JSON here")
    p.add_argument("--sweep-seeds", type=int, nargs="+", metavar="SEED",
                   help="instead: these null devices of the generalisation sweep's null sets "
                   "at their own condition (:func:`sweep_null`), e.g. 8339, the one null "
                   "false alarm of the confirmation set (docs/findings.md §6)")
    a = p.parse_args(argv)
    head = dg.commit()
    start = time.perf_counter()
    rows: list[dict[str, Any]] = []
    if a.sweep_seeds:
        for seed in a.sweep_seeds:
            r = sweep_null(seed)
            rows.append(r)
            print(f"null_bound: sweep null {seed} ({r['condition']}): identical "
                  f"{r['identical']}, ratio {r['ratio']:.4f}, found {r['found'] or '—'}, "
                  f"unexplained {r['unexplained'] or '—'}, effects written "
                  f"{r['effects_cli'] or '—'}, RMS fit / diagnose "
                  f"{r['scores']['fit'][_OFF]:.5f} / {r['scores']['diagnose'][_OFF]:.5f} °/s "
                  f"({r['seconds']:.0f} s)", flush=True)
        print(f"at commit {head}, {time.perf_counter() - start:.0f} s")
        return 0
    for refresh in REFRESH_S:
        for lsb in LSB_C:
            for seed in a.seeds:
                r = one_cell(refresh, lsb, seed)
                rows.append(r)
                print(f"null_bound: refresh {refresh:g} s LSB {lsb:g} °C seed {seed}: "
                      f"identical {r['identical']}, ratio {r['ratio']:.4f}, found "
                      f"{r['found'] or '—'} ({r['seconds']:.0f} s)", file=sys.stderr, flush=True)
    elapsed = time.perf_counter() - start
    cmd = "scripts/null_bound.py"
    if list(a.seeds) != list(SEEDS):
        cmd += " --seeds " + " ".join(map(str, a.seeds))
    header = dg.run_header(cmd, head, a.seeds, dg.FULL, elapsed)
    print(header + "\n")
    print("\n".join(cell_table(rows)))
    print("\n" + overall(rows))
    if a.json:
        dg.write_record(a.json, {"header": header, "commit": head, "elapsed_s": elapsed,
                                 "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
