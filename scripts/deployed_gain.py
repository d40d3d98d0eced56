"""Deployed gain: what an extended calibration buys on the vehicle, measured.

    .venv/bin/python scripts/deployed_gain.py [--seeds S ...] [--json OUT]
    .venv/bin/python scripts/deployed_gain.py --tables-from OUT [OUT ...]

Per effect (each of the six the diagnosis names, plus "none") and per seed of
:data:`SEEDS`, on the independent generator (:func:`gyrotherm.analysis.synth_runs`,
one device per effect and seed):

1. ``n_train`` training runs and one held-out run of the same device (the
   generator's profile is a cycle: hold, heat, hold, cool, hold, heat back);
2. on the training runs: the diagnosis and its ``--calibration`` export (the
   API ``gyrotherm diagnose --calibration`` calls: :func:`diagnose`, then
   :func:`export_calibration`) → the **extended** calibration; the **paper** model
   fitted as ``gyrotherm fit`` does (:func:`gyrotherm.compensation.fit`, pooled,
   same estimator as the extended calibration); and a PX4-style cubic in T alone
   (model ``t3``) fitted on the heating part of each training run only (power-on
   to the first maximum of the temperature reading), T_ref the midpoint of the
   calibrated T range, T clamped to that range (``Calibration`` clamps to its
   ``valid_range``, as PX4 clamps to [min_temp, max_temp]);
3. each calibration applied to the held-out run twice:

   * **offline**: :func:`gyrotherm.compensation.removed_bias` on the run's
     offline features (:func:`gyrotherm.compensation.features` with the
     calibration's estimator, i.e. ``Calibration.bias_series``; with a zero, the
     offline :func:`gyrotherm.compensation.zero_series`);
   * **deployed**: the run's CAN frames (:func:`gyrotherm.sim.frames_from_run`,
     shipped encoder) streamed through the daemon's real
     :class:`gyrotherm.daemon.Pipeline`; per rate message the bias it removed (the
     message's ``bias_dps``);

4. both scored the same way, as the **bias error** (bias removed − truth, axis x,
   the generator's one axis) on the **same rows**:

   * *no zero*: the rows whose rate message is not flagged ``ESTIMATOR_WARMUP``;
     truth = ``true_bias_dps``. RMS as it is (the held-out run's switch-on offset,
     which no calibration can know, minus the training runs' mean offset, which
     every calibration's intercept carries, is an error of every calibration) and
     with the offset removed (the error's mean over those rows taken out);
   * *with the daemon's boot-time zero* (``Pipeline(zero=ZeroConfig(window_s=W,
     settle_s=30))``; offline ``removed_bias(..., zero=...)``) for each W of
     :data:`ZERO_WINDOWS_S`: the rows from 30 s + W after the first row on (the end
     of the zero's first window, the same rows for every calibration);
     truth = true bias + the run's switch-on offset (metadata
     ``switch_on_offset_dps``), the zero removes both;

5. gain = RMS(paper) / RMS(extended), offline and deployed; the criterion:
   deployed gain ≥ :data:`TARGET_RATIO` × offline gain, offset removed (by
   subtracting the mean, or by the zero). The diagnosis' own gain (its
   leave-one-run-out residual ratio on 1-s blocks, one offset fitted per run) is
   reported beside, as the number the diagnosis promises, and the original
   criterion is also checked against it (deployed gain, offset removed).

**Seeds** (:data:`SEEDS`, 101–105) were fixed in this docstring before any of
102–105 was run through this script; 101 was the single seed of record before
(docs/findings.md §5 history), 202 and 303 the ones the review used, so they are not
in the list. The tables give the median and the range (min–max) over the seeds, and
the number of seeds on which the criterion is met.

**Cost** (measured at seed 101): the daemon's pure-Python Pipeline dominates, ≈ 90 %
of a row under cProfile (per frame: CAN decode, the estimator and compensator step on
each temperature frame, the state message). A row streams 9 times (paper and extended
without a zero and with each of the 3 windows, PX4 t3 without), ≈ 1.7 s each; the
fits take ≈ 3 s, the offline scores < 1 s: ≈ 18 s per row, 2 min per seed, ≈ 10 min
for the five seeds. Rows in two worker processes were not faster on the shared 2-core
machine (38 s against 35 s for two rows), so the rows run one after the other.

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
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis import SYNTH_EFFECTS, SynthConfig, diagnose, synth_runs
from gyrotherm.analysis._diagnose import export_calibration
from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run, StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate
from gyrotherm.compensation import (
    Calibration,
    RunFeatures,
    Scaling,
    ZeroConfig,
    ZeroStatus,
    features,
    fit,
    removed_bias,
)
from gyrotherm.daemon import Pipeline
from gyrotherm.sim import frames_from_run

FloatArray = NDArray[np.float64]
ROOT = Path(__file__).resolve().parents[1]
#: Evaluation seeds, one device per effect and seed; fixed before 102–105 were run
#: (module docstring). Not to be tuned to make a row pass.
SEEDS = (101, 102, 103, 104, 105)
SEED = SEEDS[0]
TARGET_RATIO = 0.80  # issue: deployed gain ≥ 80 % of the offline gain
NONE_TOLERANCE = 1.03  # issue: with nothing injected, extended ≤ 1.03 × paper
CALIBRATIONS = ("paper", "extended")


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


def zero_config(window_s: float) -> ZeroConfig:
    return ZeroConfig(window_s=window_s, settle_s=ZERO_SETTLE_S)


def rms(err: FloatArray) -> float:
    return float(np.sqrt(np.mean(err**2)))


def zeroed_truth(run: Run, axis: str = "x") -> FloatArray:
    """The whole slow bias the gyro outputs, true bias + switch-on offset: what a
    calibration with a boot-time zero removes."""
    return run.true_bias_dps[axis] + float(run.metadata["switch_on_offset_dps"])


def zeroed_rows(run: Run, from_s: float) -> NDArray[np.bool_]:
    """Rows from ``from_s`` after the run's first row on."""
    t = run.time_s - run.time_s[0]
    return np.asarray(t >= from_s)


def zeroed_error(run: Run, removed: FloatArray, from_s: float, axis: str = "x") -> float:
    """RMS error of the bias removed by a daemon running the boot-time zero: the zero
    also takes out the run's switch-on offset, so the truth is the whole slow bias
    the gyro outputs, true bias + switch-on offset (the generator's metadata
    ``switch_on_offset_dps``), scored from ``from_s`` after the run's first row (the
    end of the zero's first window: the same rows for every calibration, also when
    its zero was refused or is still pending there)."""
    after = zeroed_rows(run, from_s)
    return rms(removed[after] - zeroed_truth(run, axis)[after])


@dataclass(frozen=True)
class Streamed:
    """One calibration streamed through the daemon's Pipeline over one run."""

    removed_dps: FloatArray
    """Bias removed on each row (the rate message's ``bias_dps``), °/s."""
    ready: NDArray[np.bool_]
    """Rows whose rate message is not flagged ``ESTIMATOR_WARMUP``."""
    zero: str
    """How the zero ended ("off" without one; "done at 40 s", "pending", …)."""


def _zero_text(status: ZeroStatus, done_s: float, t0_s: float) -> str:
    return status.name.lower() + (f" at {done_s - t0_s:.0f} s" if status == ZeroStatus.DONE
                                  else "")


def stream(run: Run, frames: Sequence[can.Message], calibration: Calibration,
           zero: ZeroConfig | None, axis: str = "x") -> Streamed:
    """``frames`` (the CAN frames of ``run``) through a fresh daemon Pipeline."""
    sink = _Sink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=calibration, zero=zero)
    for msg in frames:
        pipe.process(msg, 1.0e9)
    if pipe.counters().drops:
        raise RuntimeError(f"{run.name}: the pipeline dropped frames {pipe.counters().drops}")
    msgs = [decode_rate(p) for p in sink.rates]
    if len(msgs) != len(run):
        raise RuntimeError(f"{run.name}: {len(msgs)} rate messages for {len(run)} rows")
    j = "xyz".index(axis)
    removed = np.array([m.bias_dps[j] for m in msgs])
    ready = np.array([not (m.flags & StatusFlags.ESTIMATOR_WARMUP) for m in msgs])
    z = pipe.compensation.zero
    text = "off" if z is None else _zero_text(z.status, z.done_s, float(run.time_s[0]))
    return Streamed(removed, ready, text)


def offline(run: RunFeatures, calibration: Calibration, zero: ZeroConfig | None,
            axis: str = "x") -> tuple[FloatArray, str]:
    """The bias the same calibration removes offline (``removed_bias`` on the run's
    offline features; with the offline zero) and how the zero ended."""
    rb = removed_bias(calibration, run, zero=zero)
    z = rb.zero
    text = "off" if z is None else _zero_text(z.status, z.done_s, float(run.time_s[0]))
    return rb.bias[axis][0], text


def score(removed: Mapping[str, FloatArray], truth: FloatArray,
          rows: NDArray[np.bool_]) -> dict[str, dict[str, float]]:
    """Per calibration: RMS, RMS with the mean error taken out, and the mean error of
    ``removed − truth`` on ``rows``."""
    out: dict[str, dict[str, float]] = {}
    for name, r in removed.items():
        err = (r - truth)[rows]
        mean = float(np.mean(err))
        out[name] = {"rms": rms(err), "rms_offset_removed": rms(err - mean), "mean": mean}
    return out


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


def one_effect(effect: str, s: Settings, seed: int = SEED,
               windows: Sequence[float] = ZERO_WINDOWS_S, px4: bool = True) -> dict[str, Any]:
    """Everything for one row of the tables, one seed (``effect`` "none": nothing
    injected). ``no_zero`` and ``zero`` (by window, s) hold per source (``offline``,
    ``deployed``) and calibration the :func:`score` on the rows the deployed score
    uses; ``zero`` also ``no_zero_same_rows`` (the deployed score without a zero on
    the zero's rows: the baseline the zero changes) and the zeros' status."""
    effects: dict[str, dict[str, float]] = {} if effect == "none" else {effect: {}}
    cfg = SynthConfig(duration_s=s.duration_s, rate_hz=s.rate_hz, effects=effects)
    runs, truth = synth_runs(cfg, n_runs=s.n_train + 1, seed=seed)
    train, held = runs[:-1], runs[-1]
    start = time.perf_counter()
    result = diagnose(train, simulate=False)
    extended = export_calibration(train, result).calibration
    paper = fit([features(r, extended.estimator) for r in train], "paper",
                estimator=extended.estimator)
    cals = {"paper": paper, "extended": extended}
    if px4:
        cals["px4_t3"] = px4_cubic(train, extended)
    fit_s = time.perf_counter() - start
    start = time.perf_counter()
    frames = list(frames_from_run(held, encoder=FrameEncoder()))
    feats = features(held, extended.estimator)
    true = held.true_bias_dps["x"]
    nz = {k: stream(held, frames, c, None) for k, c in cals.items()}
    ready = nz["paper"].ready
    for k, v in nz.items():
        if not np.array_equal(v.ready, ready):
            raise RuntimeError(f"{k}: other warm-up rows than paper's")
    off_nz = {k: offline(feats, cals[k], None)[0] for k in CALIBRATIONS}
    row: dict[str, Any] = {
        "effect": effect,
        "seed": seed,
        "injected": {k: dict(v) for k, v in truth.effects.items()},
        "found": sorted(f.effect for f in result.findings),
        "extended_effects": list(extended.effect_names("x")) if "x" in extended.axes else [],
        "diagnosis_gain": result.gain,
        "no_zero": {"rows": int(ready.sum()),
                    "deployed": score({k: v.removed_dps for k, v in nz.items()}, true, ready),
                    "offline": score(off_nz, true, ready)},
        "zero": {},
    }
    whole = zeroed_truth(held)
    for w in windows:
        z = zero_config(w)
        rows = zeroed_rows(held, ZERO_SETTLE_S + w)
        dep = {k: stream(held, frames, cals[k], z) for k in CALIBRATIONS}
        off = {k: offline(feats, cals[k], z) for k in CALIBRATIONS}
        row["zero"][str(w)] = {
            "rows": int(rows.sum()),
            "deployed": score({k: v.removed_dps for k, v in dep.items()}, whole, rows),
            "offline": score({k: v[0] for k, v in off.items()}, whole, rows),
            "no_zero_same_rows": score({k: nz[k].removed_dps for k in CALIBRATIONS}, true, rows),
            "status": {"deployed": {k: v.zero for k, v in dep.items()},
                       "offline": {k: v[1] for k, v in off.items()}},
        }
    row["fit_s"] = fit_s
    row["apply_s"] = time.perf_counter() - start
    return row


# --- gains and the criterion ---------------------------------------------------------


def gain(scores: Mapping[str, Mapping[str, float]], key: str = "rms") -> float:
    """RMS(paper) / RMS(extended) of one :func:`score`."""
    return scores["paper"][key] / scores["extended"][key]


def cell(row: Mapping[str, Any], window: str | None) -> Mapping[str, Any]:
    """``row``'s scores without a zero (``window`` None) or with the zero ``window``."""
    out: Mapping[str, Any] = row["no_zero"] if window is None else row["zero"][window]
    return out


def offset_removed_key(window: str | None) -> str:
    """Without a zero the offset is removed by subtracting the mean error; with one,
    the zero removed it."""
    return "rms_offset_removed" if window is None else "rms"


def ratio(row: Mapping[str, Any], window: str | None) -> float:
    """Deployed gain / offline gain, offset removed."""
    c, key = cell(row, window), offset_removed_key(window)
    return gain(c["deployed"], key) / gain(c["offline"], key)


def met(row: Mapping[str, Any], window: str | None) -> bool:
    """The criterion for one seed: deployed ≥ 80 % of offline, offset removed; with
    nothing injected, extended ≤ 1.03 × paper on the stream."""
    c, key = cell(row, window), offset_removed_key(window)
    if row["effect"] == "none":
        return 1.0 / gain(c["deployed"], key) <= NONE_TOLERANCE
    return ratio(row, window) >= TARGET_RATIO


def vs_diagnosis(row: Mapping[str, Any], window: str | None) -> float:
    """Deployed gain, offset removed, / the diagnosis' own (leave-one-run-out) gain:
    the original criterion's form, the number the diagnosis promises as denominator."""
    c, key = cell(row, window), offset_removed_key(window)
    return gain(c["deployed"], key) / float(row["diagnosis_gain"])


@dataclass(frozen=True)
class Spread:
    """Median and range (min–max) of one quantity over the seeds."""

    median: float
    low: float
    high: float

    @classmethod
    def of(cls, values: Iterable[float]) -> Spread:
        v = np.asarray(list(values), dtype=np.float64)
        return cls(float(np.median(v)), float(v.min()), float(v.max()))

    def text(self, fmt: str = ".2f", scale: float = 1.0, unit: str = "") -> str:
        m, lo, hi = (format(scale * x, fmt) for x in (self.median, self.low, self.high))
        return f"{m}{unit} [{lo}–{hi}]"


def by_effect(rows: Sequence[Mapping[str, Any]]) -> dict[str, list[Mapping[str, Any]]]:
    """Rows grouped by effect, in first-seen order, each group sorted by seed."""
    out: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        out.setdefault(r["effect"], []).append(r)
    return {k: sorted(v, key=lambda r: int(r["seed"])) for k, v in out.items()}


def _over(group: Sequence[Mapping[str, Any]], f: Callable[[Mapping[str, Any]], float]) -> Spread:
    return Spread.of(f(r) for r in group)


def _count(group: Sequence[Mapping[str, Any]], f: Callable[[Mapping[str, Any]], bool]) -> str:
    return f"{sum(1 for r in group if f(r))}/{len(group)}"


_OFF = "rms_offset_removed"


def _no_zero_cells(effect: str, g: Sequence[Mapping[str, Any]]) -> list[str]:
    def src(r: Mapping[str, Any], source: str, key: str = "rms") -> float:
        return gain(r["no_zero"][source], key)

    if effect == "none":
        found = "false alarm " + _count(g, lambda r: bool(r["found"]))
        worse = _over(g, lambda r: 1.0 / src(r, "deployed", _OFF)).text(".3f")
        crit = f"extended / paper {worse} ≤ {NONE_TOLERANCE}: {_count(g, lambda r: met(r, None))}"
        original = "—"
    else:
        found = _count(g, lambda r: effect in r["found"])
        crit = _count(g, lambda r: met(r, None))
        original = _count(g, lambda r: vs_diagnosis(r, None) >= TARGET_RATIO)
    cals = [c for c in ("paper", "extended", "px4_t3") if c in g[0]["no_zero"]["deployed"]]
    med = [float(np.median([r["no_zero"]["deployed"][c]["rms"] for r in g])) for c in cals]
    return [
        effect, found, _over(g, lambda r: float(r["diagnosis_gain"])).text(),
        _over(g, lambda r: src(r, "offline")).text(),
        _over(g, lambda r: src(r, "deployed")).text(),
        _over(g, lambda r: src(r, "offline", _OFF)).text(),
        _over(g, lambda r: src(r, "deployed", _OFF)).text(),
        _over(g, lambda r: ratio(r, None)).text(".0f", 100, " %"), crit,
        _over(g, lambda r: vs_diagnosis(r, None)).text(".0f", 100, " %"), original,
        " / ".join(f"{v:.4f}" for v in med),
    ]


def no_zero_table(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Without a zero: per effect, median [min–max] over the seeds."""
    out = [
        "| injected | found (seeds) | diagnosis' gain (LORO, 1-s blocks) | offline gain | "
        "deployed gain | offline gain, offset removed | deployed gain, offset removed | "
        "deployed / offline, offset removed | criterion met (seeds) | "
        "deployed, offset removed / diagnosis' gain | ≥ 80 % of diagnosis' (seeds) | "
        "RMS deployed paper / extended / PX4 t3 °/s (medians) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for effect, g in by_effect(rows).items():
        out.append("| " + " | ".join(_no_zero_cells(effect, g)) + " |")
    return out


def _zero_cells(effect: str, w: str, g: Sequence[Mapping[str, Any]]) -> list[str]:
    def z(r: Mapping[str, Any]) -> Mapping[str, Any]:
        out: Mapping[str, Any] = r["zero"][w]
        return out

    def base(c: str, r: Mapping[str, Any], key: str = _OFF) -> float:
        return float(z(r)["no_zero_same_rows"][c][key])

    def zeroed(c: str, r: Mapping[str, Any]) -> float:
        return float(z(r)["deployed"][c]["rms"])

    rms_cells = []
    for c in CALIBRATIONS:
        raw = float(np.median([base(c, r, "rms") for r in g]))
        b = float(np.median([base(c, r) for r in g]))
        after = float(np.median([zeroed(c, r) for r in g]))
        x = Spread.of(zeroed(c, r) / base(c, r) for r in g)
        rms_cells.append(f"{raw:.4f} / {b:.4f} → {after:.4f} (×{x.text()})")
    statuses = [s for r in g for src in ("deployed", "offline")
                for s in z(r)["status"][src].values()]
    accepted = f"{sum(s.startswith('done') for s in statuses)}/{len(statuses)}"
    crit = _count(g, lambda r: met(r, w))
    if effect == "none":
        worse = _over(g, lambda r: 1.0 / gain(z(r)["deployed"])).text(".3f")
        crit = f"extended / paper {worse} ≤ {NONE_TOLERANCE}: {crit}"
    return [
        effect, f"{float(w):g} s",
        _over(g, lambda r: gain(z(r)["offline"])).text(),
        _over(g, lambda r: gain(z(r)["deployed"])).text(),
        _over(g, lambda r: ratio(r, w)).text(".0f", 100, " %"), crit, *rms_cells, accepted,
    ]


def zero_table(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """With the daemon's boot-time zero: per effect and window, median [min–max] over
    the seeds; beside it what the zero does to each calibration's error: its RMS
    without a zero on the same rows (medians: as it is, and with the offset removed)
    → with the zero (median), and the ratio with / without, offset removed (median
    [min–max]); "zeros accepted" counts offline and deployed, paper and extended."""
    out = [
        "| injected | zero W | offline gain | deployed gain | deployed / offline | "
        "criterion met (seeds) | paper RMS °/s: no zero (as is / offset removed) → zero W "
        "(× offset removed) | extended RMS °/s: the same | zeros accepted |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for effect, g in by_effect(rows).items():
        for w in g[0]["zero"]:
            out.append("| " + " | ".join(_zero_cells(effect, w, g)) + " |")
    return out


def criterion_table(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The criterion per effect, seeds where it is met: deployed ≥ 80 % of offline (the
    same quantity) and, the original form, ≥ 80 % of the diagnosis' gain; offset removed
    by subtracting the mean (no zero) or by the zero. Nothing injected: extended ≤ 1.03
    × paper on the stream (the diagnosis' gain is 1 by definition: —)."""
    groups = by_effect(rows)
    windows: list[str | None] = [None, *next(iter(groups.values()))[0]["zero"]]
    names = ["no zero" if w is None else f"zero {float(w):g} s" for w in windows]
    out = ["| injected | " + " | ".join(f"≥ 80 % of offline: {n}" for n in names) + " | "
           + " | ".join(f"≥ 80 % of diagnosis': {n}" for n in names) + " |",
           "|---|" + "---|" * (2 * len(windows))]

    def met_at(w: str | None) -> Callable[[Mapping[str, Any]], bool]:
        return lambda r: met(r, w)

    def promised_at(w: str | None) -> Callable[[Mapping[str, Any]], bool]:
        return lambda r: vs_diagnosis(r, w) >= TARGET_RATIO

    for effect, g in groups.items():
        same = [_count(g, met_at(w)) for w in windows]
        diag = (["—"] * len(windows) if effect == "none"
                else [_count(g, promised_at(w)) for w in windows])
        out.append(f"| {effect} | " + " | ".join(same + diag) + " |")
    return out


def run_header(cmd: str, at_commit: str, seeds: Sequence[int], s: Settings,
               elapsed_s: float) -> str:
    """The line a study's tables are printed under: the command, the commit, the seeds,
    the run design and the run time."""
    return (f"`.venv/bin/python {cmd}` at commit {at_commit}, seeds "
            f"{', '.join(map(str, seeds))}, {s.n_train} training runs + 1 held-out, "
            f"{s.duration_s:g} s at {s.rate_hz:g} Hz, {elapsed_s:.0f} s")


def write_record(path: str, record: Mapping[str, Any]) -> None:
    """A study's ``--json`` output (parent directories created)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(dict(record), indent=2) + "\n", encoding="utf-8")


def read_records(paths: Sequence[str]) -> tuple[list[dict[str, Any]], list[str]]:
    """``--tables-from``: the rows and headers of earlier ``--json`` outputs, merged."""
    docs = [json.loads(Path(f).read_text(encoding="utf-8")) for f in paths]
    return [r for d in docs for r in d["rows"]], [d["header"] for d in docs]


def print_report(heads: Sequence[str], *tables: Sequence[str]) -> None:
    """The headers, then each table, a blank line between."""
    print("\n".join(heads))
    for table in tables:
        print()
        print("\n".join(table))


def commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, check=True,
                             capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src", "scripts"],
                               cwd=ROOT, check=True, capture_output=True, text=True).stdout
        return out + ("+uncommitted" if dirty.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_rows(effects: Sequence[str], seeds: Sequence[int], s: Settings) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    for seed in seeds:
        for effect in effects:
            r = one_effect(effect, s, seed)
            rows.append(r)
            print(f"deployed_gain: seed {seed} {effect}: no zero, offset removed: offline "
                  f"{gain(r['no_zero']['offline'], _OFF):.2f}, deployed "
                  f"{gain(r['no_zero']['deployed'], _OFF):.2f} "
                  f"({r['fit_s']:.0f} + {r['apply_s']:.0f} s)", file=sys.stderr, flush=True)
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true",
                   help=f"shorter runs ({QUICK.duration_s:g} s at {QUICK.rate_hz:g} Hz, "
                   f"{QUICK.n_train} training runs) instead of {FULL.duration_s:g} s at "
                   f"{FULL.rate_hz:g} Hz, {FULL.n_train}")
    p.add_argument("--json", metavar="OUT", help="also write the rows as JSON here")
    p.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS),
                   help=f"generator seeds (default {' '.join(map(str, SEEDS))}, the ones of "
                   "record; others are robustness checks)")
    p.add_argument("--effects", nargs="+", choices=(*SYNTH_EFFECTS, "none"),
                   default=[*SYNTH_EFFECTS, "none"], help="subset of rows (default: all)")
    p.add_argument("--tables-from", nargs="+", metavar="JSON",
                   help="print the tables of earlier --json outputs (merged) instead of running")
    args = p.parse_args(argv)
    if args.tables_from:
        rows, heads = read_records(args.tables_from)
    else:
        s = QUICK if args.quick else FULL
        start = time.perf_counter()
        rows = run_rows(args.effects, args.seeds, s)
        elapsed = time.perf_counter() - start
        cmd = "scripts/deployed_gain.py" + (" --quick" if args.quick else "")
        if list(args.seeds) != list(SEEDS):
            cmd += " --seeds " + " ".join(map(str, args.seeds))
        at_commit = commit()
        heads = [run_header(cmd, at_commit, args.seeds, s, elapsed)]
        if args.json:
            write_record(args.json, {"header": heads[0], "settings": s.__dict__,
                                     "seeds": list(args.seeds), "commit": at_commit,
                                     "elapsed_s": elapsed, "rows": rows})
    print_report(heads, no_zero_table(rows), zero_table(rows), criterion_table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
