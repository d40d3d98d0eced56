"""Deployed gain: what an extended calibration buys on the vehicle, measured.

    .venv/bin/python scripts/deployed_gain.py [--quick] [--json OUT]

Per effect (each of the six the diagnosis names, plus "none"), on the independent
generator (:func:`gyrotherm.analysis.synth_runs`, one device per effect, seed fixed
below before any result was seen):

1. ``n_train`` training runs and one held-out run of the same device (the
   generator's profile is a cycle: hold, heat, hold, cool, hold, heat back);
2. on the training runs: the diagnosis and its ``--calibration`` export (the
   API ``gyrotherm diagnose --calibration`` calls: :func:`diagnose`, then
   :func:`export_calibration`) → the extended calibration; the paper model
   fitted as ``gyrotherm fit`` does (:func:`gyrotherm.compensation.fit`, pooled,
   same estimator as the extended calibration); and a PX4-style cubic in T alone
   (model ``t3``) fitted on the heating part of each training run only (power-on
   to the first maximum of the temperature reading), T_ref the midpoint of the
   calibrated T range, T clamped to that range (``Calibration`` clamps to its
   ``valid_range``, as PX4 clamps to [min_temp, max_temp]);
3. the held-out run's CAN frames (:func:`gyrotherm.sim.frames_from_run`, shipped
   encoder) streamed through the daemon's real :class:`gyrotherm.daemon.Pipeline`
   with each calibration; per rate message the bias it removed (the message's
   ``bias_dps``) minus the run's ``true_bias_dps``, rows flagged
   ``ESTIMATOR_WARMUP`` left out → RMS per calibration (axis x, the generator's
   one axis);
4. deployed gain = RMS(paper) / RMS(extended) against the diagnosis' offline gain.

The two gains measure different things: the offline gain is the diagnosis'
leave-one-run-out RMS ratio of the *measured rate* residual (1-s block means,
one offset fitted per run, so switch-on offsets and noise are in both numerator
and denominator); the deployed gain is the RMS ratio of the *bias error* on the
raw 10 Hz stream of one unseen run, with no offset removed (the run's switch-on
offset is in neither the calibration nor the truth, so it is an error of every
calibration, and neither is the mean of the training runs' offsets, which the
calibration's intercept absorbs). The "mean removed" column takes out the mean
error to show that part.

``--quick`` (half-length runs at 5 Hz, 3 training runs) is for trying the script:
its shorter runs ramp faster, the causal estimator's ΔT lags more, and that
transient error, common to paper and extended models, dominates both RMS values.
The default settings are the ones of record (docs/findings.md, the test).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.analysis import SYNTH_EFFECTS, SynthConfig, diagnose, synth_runs
from gyrotherm.analysis._diagnose import export_calibration
from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run, StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate
from gyrotherm.compensation import Calibration, Scaling, ZeroConfig, ZeroStatus, features, fit
from gyrotherm.daemon import Pipeline
from gyrotherm.sim import frames_from_run

ROOT = Path(__file__).resolve().parents[1]
#: One device per effect; fixed before any deployed-gain result was seen (the seed
#: the hidden-effect tests use first). Not to be tuned to make a row pass.
SEED = 101
TARGET_RATIO = 0.80  # issue: deployed gain ≥ 80 % of the offline gain
NONE_TOLERANCE = 1.03  # issue: with nothing injected, extended ≤ 1.03 × paper


@dataclass(frozen=True)
class Settings:
    duration_s: float
    rate_hz: float
    n_train: int


FULL = Settings(duration_s=6000.0, rate_hz=10.0, n_train=4)
QUICK = Settings(duration_s=3000.0, rate_hz=5.0, n_train=3)


class _Sink:
    """Keeps the daemon's rate messages (a RecordingSink without the states)."""

    def __init__(self) -> None:
        self.rates: list[bytes] = []

    def put_rate(self, payload: bytes) -> None:
        self.rates.append(payload)

    def put_state(self, payload: bytes) -> None:
        pass


ZERO_WINDOWS_S = (10.0, 60.0, 300.0)
"""Boot-time zero windows tried (s at rest; the daemon's ``[zero] window_s``)."""
ZERO_SETTLE_S = 30.0
"""``[zero] settle_s``: past the estimator's warm-up (20 readings of a sensor that
refreshes every 1.28 s ≈ 25 s; also the default); the other ``[zero]`` keys keep
their defaults."""


@dataclass(frozen=True)
class Streamed:
    """Bias error (removed − true) of one calibration on one run, after warm-up; and,
    per boot-time zero window (s), the RMS error with the daemon's zero (see
    :func:`zeroed_error`) and how the zero ended."""

    rms_dps: float
    std_dps: float
    mean_dps: float
    rows: int
    zeroed_rms_dps: dict[float, float]
    zero_status: dict[float, str]


def zeroed_error(run: Run, removed: np.ndarray, from_s: float, axis: str = "x") -> float:
    """RMS error of the bias removed by a daemon running the boot-time zero: the zero
    also takes out the run's switch-on offset, so the truth is the whole slow bias
    the gyro outputs, true bias + switch-on offset (the generator's metadata
    ``switch_on_offset_dps``), scored from ``from_s`` after the run's first row (the
    end of the zero's first window: the same rows for every calibration, also when
    its zero was refused or is still pending there)."""
    t = run.time_s - run.time_s[0]
    after = t >= from_s
    truth = run.true_bias_dps[axis] + float(run.metadata["switch_on_offset_dps"])
    err = removed[after] - truth[after]
    return float(np.sqrt(np.mean(err**2)))


def _stream(run: Run, calibration: Calibration, zero: ZeroConfig | None,
            axis: str) -> tuple[np.ndarray, np.ndarray, Pipeline]:
    sink = _Sink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=calibration, zero=zero)
    for msg in frames_from_run(run, encoder=FrameEncoder()):
        pipe.process(msg, 1.0e9)
    if pipe.counters().drops:
        raise RuntimeError(f"{run.name}: the pipeline dropped frames {pipe.counters().drops}")
    msgs = [decode_rate(p) for p in sink.rates]
    if len(msgs) != len(run):
        raise RuntimeError(f"{run.name}: {len(msgs)} rate messages for {len(run)} rows")
    j = "xyz".index(axis)
    removed = np.array([m.bias_dps[j] for m in msgs])
    ready = np.array([not (m.flags & StatusFlags.ESTIMATOR_WARMUP) for m in msgs])
    return removed, ready, pipe


def stream_error(run: Run, calibration: Calibration, axis: str = "x") -> Streamed:
    """Stream ``run`` through the daemon's Pipeline with ``calibration``: without a
    zero, the bias it removed minus the run's true bias over rate messages past the
    estimator warm-up; and once per window of :data:`ZERO_WINDOWS_S` with the
    daemon's boot-time zero (``Pipeline(zero=...)``, :func:`zeroed_error`)."""
    removed, ready, _ = _stream(run, calibration, None, axis)
    err = (removed - run.true_bias_dps[axis])[ready]
    zeroed, status = {}, {}
    for w in ZERO_WINDOWS_S:
        removed_z, _, pipe = _stream(run, calibration,
                                     ZeroConfig(window_s=w, settle_s=ZERO_SETTLE_S), axis)
        zeroed[w] = zeroed_error(run, removed_z, ZERO_SETTLE_S + w, axis)
        zero = pipe.compensation.zero
        assert zero is not None
        status[w] = zero.status.name.lower() + (
            f" at {zero.done_s - run.time_s[0]:.0f} s" if zero.status == ZeroStatus.DONE else "")
    return Streamed(rms_dps=float(np.sqrt(np.mean(err**2))), std_dps=float(np.std(err)),
                    mean_dps=float(np.mean(err)), rows=int(ready.sum()),
                    zeroed_rms_dps=zeroed, zero_status=status)


def heating_part(run: Run) -> Run:
    """Power-on to the first maximum of the temperature reading (a PX4 thermal
    calibration logs a cold-soaked vehicle warming up)."""
    return run.slice(0, int(np.argmax(run.temperature_c)) + 1)


def px4_cubic(train: Sequence[Run], calibration: Calibration) -> Calibration:
    """Cubic in T alone on heating data, T_ref the middle of the calibrated range."""
    heat = [features(heating_part(r), calibration.estimator) for r in train]
    t = np.concatenate([f.temperature_c for f in heat])
    lo, hi = float(t.min()), float(t.max())
    scaling = Scaling(t_ref_c=(lo + hi) / 2, t_scale_c=max((hi - lo) / 2, 1.0), dt_scale_c=1.0)
    return fit(heat, "t3", estimator=calibration.estimator, scaling=scaling)


def one_effect(effect: str, s: Settings, seed: int = SEED) -> dict[str, Any]:
    """Everything for one row of the table (``effect`` "none": nothing injected)."""
    effects: dict[str, dict[str, float]] = {} if effect == "none" else {effect: {}}
    cfg = SynthConfig(duration_s=s.duration_s, rate_hz=s.rate_hz, effects=effects)
    runs, truth = synth_runs(cfg, n_runs=s.n_train + 1, seed=seed)
    train, held = runs[:-1], runs[-1]
    start = time.perf_counter()
    result = diagnose(train, simulate=False)
    extended = export_calibration(train, result).calibration
    paper = fit([features(r, extended.estimator) for r in train], "paper",
                estimator=extended.estimator)
    cubic = px4_cubic(train, extended)
    fit_s = time.perf_counter() - start
    errors = {name: stream_error(held, cal)
              for name, cal in (("paper", paper), ("extended", extended), ("px4_t3", cubic))}
    deployed = errors["paper"].rms_dps / errors["extended"].rms_dps
    offline = result.gain
    found = {f.effect: f.gain for f in result.findings}
    row: dict[str, Any] = {
        "effect": effect,
        "injected": {k: dict(v) for k, v in truth.effects.items()},
        "found": sorted(found),
        "extended_effects": list(extended.effect_names("x")) if "x" in extended.axes else [],
        "offline_gain": offline,
        "offline_gain_of_effect": found.get(effect),
        "deployed_gain": deployed,
        "deployed_over_offline": deployed / offline,
        "rms_dps": {k: v.rms_dps for k, v in errors.items()},
        "std_dps": {k: v.std_dps for k, v in errors.items()},
        "mean_dps": {k: v.mean_dps for k, v in errors.items()},
        "deployed_gain_std": errors["paper"].std_dps / errors["extended"].std_dps,
        "zeroed": {str(w): {"rms_dps": {k: v.zeroed_rms_dps[w] for k, v in errors.items()},
                            "status": {k: v.zero_status[w] for k, v in errors.items()},
                            "deployed_gain": errors["paper"].zeroed_rms_dps[w]
                            / errors["extended"].zeroed_rms_dps[w]}
                   for w in ZERO_WINDOWS_S},
        "rows_scored": errors["paper"].rows,
        "fit_s": fit_s,
    }
    if effect == "none":
        row["extended_over_paper"] = errors["extended"].rms_dps / errors["paper"].rms_dps
        row["pass"] = row["extended_over_paper"] <= NONE_TOLERANCE
    else:
        row["pass"] = row["deployed_over_offline"] >= TARGET_RATIO
    return row


def table(rows: Sequence[dict[str, Any]]) -> list[str]:
    out = [
        "| injected | found | offline gain | deployed gain | deployed / offline | "
        "RMS paper °/s | RMS extended °/s | RMS PX4 t3 °/s | mean error paper / extended °/s | "
        "deployed gain, mean removed (/ offline) | target met |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        rms = r["rms_dps"]
        if r["effect"] == "none":
            target = (f"extended/paper {r['extended_over_paper']:.3f} ≤ {NONE_TOLERANCE}: "
                      + ("yes" if r["pass"] else "**no**"))
        else:
            target = "yes" if r["pass"] else "**no**"
        out.append(
            f"| {r['effect']} | {', '.join(r['found']) or '—'} | {r['offline_gain']:.2f} | "
            f"{r['deployed_gain']:.2f} | {100 * r['deployed_over_offline']:.0f} % | "
            f"{rms['paper']:.4f} | {rms['extended']:.4f} | {rms['px4_t3']:.4f} | "
            f"{r['mean_dps']['paper']:+.4f} / {r['mean_dps']['extended']:+.4f} | "
            f"{r['deployed_gain_std']:.2f} "
            f"({100 * r['deployed_gain_std'] / r['offline_gain']:.0f} %) | {target} |")
    return out


def zero_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    """With the daemon's boot-time zero: deployed gain (and / offline) per window."""
    head = " | ".join(f"zero {w:g} s: gain (/ offline), RMS paper / extended °/s"
                      for w in ZERO_WINDOWS_S)
    out = [f"| injected | offline gain | no zero: gain (/ offline) | {head} |",
           "|---|---|---|" + "---|" * len(ZERO_WINDOWS_S)]
    for r in rows:
        cells = []
        for w in ZERO_WINDOWS_S:
            z = r["zeroed"][str(w)]
            share = 100 * z["deployed_gain"] / r["offline_gain"]
            odd = [f"{k} zero {v}" for k, v in z["status"].items()
                   if k != "px4_t3" and not v.startswith("done")]
            cells.append(f"{z['deployed_gain']:.2f} ({share:.0f} %), "
                         f"{z['rms_dps']['paper']:.4f} / {z['rms_dps']['extended']:.4f}"
                         + (f" ({'; '.join(odd)})" if odd else ""))
        out.append(f"| {r['effect']} | {r['offline_gain']:.2f} | {r['deployed_gain']:.2f} "
                   f"({100 * r['deployed_over_offline']:.0f} %) | " + " | ".join(cells) + " |")
    return out


def commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, check=True,
                             capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src", "scripts"],
                               cwd=ROOT, check=True, capture_output=True, text=True).stdout
        return out + ("+uncommitted" if dirty.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true",
                   help=f"shorter runs ({QUICK.duration_s:g} s at {QUICK.rate_hz:g} Hz, "
                   f"{QUICK.n_train} training runs) instead of {FULL.duration_s:g} s at "
                   f"{FULL.rate_hz:g} Hz, {FULL.n_train}")
    p.add_argument("--json", metavar="OUT", help="also write the rows as JSON here")
    p.add_argument("--seed", type=int, default=SEED,
                   help=f"generator seed (default {SEED}, the one of record; others are "
                   "robustness checks, docs/findings.md §5)")
    p.add_argument("--effects", nargs="+", choices=(*SYNTH_EFFECTS, "none"),
                   default=[*SYNTH_EFFECTS, "none"], help="subset of rows (default: all)")
    args = p.parse_args(argv)
    s = QUICK if args.quick else FULL
    start = time.perf_counter()
    rows = []
    for effect in args.effects:
        rows.append(one_effect(effect, s, args.seed))
        r = rows[-1]
        print(f"deployed_gain: {effect}: offline {r['offline_gain']:.2f}, deployed "
              f"{r['deployed_gain']:.2f} ({100 * r['deployed_over_offline']:.0f} %)",
              file=sys.stderr, flush=True)
    elapsed = time.perf_counter() - start
    cmd = "scripts/deployed_gain.py" + (" --quick" if args.quick else "")
    cmd += f" --seed {args.seed}" if args.seed != SEED else ""
    print(f"`.venv/bin/python {cmd}` at commit {commit()}, seed {args.seed}, "
          f"{s.n_train} training runs + 1 held-out, {s.duration_s:g} s at {s.rate_hz:g} Hz, "
          f"{elapsed:.0f} s")
    print()
    print("\n".join(table(rows)))
    print()
    print("\n".join(zero_table(rows)))
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"settings": s.__dict__, "seed": args.seed, "commit": commit(),
                                   "elapsed_s": elapsed, "rows": rows}, indent=2) + "\n",
                       encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
