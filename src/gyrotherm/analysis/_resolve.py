"""What the diagnosis' temperature estimate can resolve in time.

A ``thermal_lag`` of time constant τ delays the temperature the bias sees.
Its first-order part, τ·dT/dt, is absorbed by the ΔT terms; what identifies a
lag is its shape after each ramp corner, which lasts ≈ τ. The temperature
feature cannot show timing finer than the largest of

* the readout's update period P (a reading is held for P),
* the time the ramps need to cross one readout LSB q, q / |dT/dt|, with
  |dT/dt| the median rate over the blocks whose |dT/dt| exceeds
  :data:`~._stats.RATE_THRESHOLD_C_PER_S` (a quantised reading changes only
  once per LSB crossed),
* half the window of the zero-phase smoother of ``features="smooth"``
  (:data:`SMOOTH_T_WINDOW_S` / 2; 1-s blocks for ``"kalman"``).

τ_min = max of these. A lag fitted below τ_min is not a physical finding (the
fit found timing the readout cannot show).

A lag *above* τ_min can still be the readout's doing: with a coarse LSB the
smoothed reading keeps a ripple of up to ~q/2 between code changes, which a
lagged temperature smooths away, so a lag buys held-out gain where none
exists. So the lag's held-out gain is compared with the gain a lag buys on
replays of the runs in which no lag exists (:func:`replay_lag_gain`: the model
without the lag on a step-free temperature history, re-read through the same
readout and smoother); the lag must beat the largest null gain of
:data:`NULL_REPLAYS` replays by the selection's margin.

An unresolved lag is left out of the model and named in the notes with the
reason.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from gyrotherm.analysis._effects import design
from gyrotherm.analysis._prep import BLOCK_S, Prepared, Readout
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._stats import RATE_THRESHOLD_C_PER_S

FloatArray = NDArray[np.float64]
SMOOTH_T_WINDOW_S = 31.0
"""Window (s) of the Savitzky–Golay fit that gives T in :func:`~._prep.prepare`."""


@dataclass(frozen=True)
class LagLimit:
    """τ_min (s) and its three candidates."""

    hold_s: float
    lsb_crossing_s: float
    smoother_s: float

    @property
    def tau_min_s(self) -> float:
        return max(self.hold_s, self.lsb_crossing_s, self.smoother_s)

    def reason(self) -> str:
        parts = {"readout hold period": self.hold_s,
                 "time to cross one readout LSB on the ramps": self.lsb_crossing_s,
                 "half the temperature smoother's window": self.smoother_s}
        which = max(parts, key=lambda k: parts[k])
        return f"τ_min = {self.tau_min_s:.1f} s, set by the {which}"


def lag_limit(
    readouts: Sequence[Readout], runs: Sequence[Prepared], *, features: str = "smooth"
) -> LagLimit:
    """τ_min for these readouts and runs (module docstring)."""
    hold = float(np.median([r.period_s for r in readouts]))
    lsb = float(np.median([r.lsb_c for r in readouts]))
    rate = np.abs(np.concatenate([p.rate_c_per_s for p in runs]))
    ramp = rate[rate > RATE_THRESHOLD_C_PER_S]
    crossing = lsb / float(np.median(ramp)) if len(ramp) and lsb > 0 else 0.0
    smoother = SMOOTH_T_WINDOW_S / 2.0 if features == "smooth" else BLOCK_S
    return LagLimit(hold_s=hold, lsb_crossing_s=crossing, smoother_s=smoother)


def drop_unresolved_lag(
    selector: Selector, final: Evaluation, limit: LagLimit, readouts: Sequence[Readout],
    *, margin: float = 0.10, seed: int = 0,
) -> tuple[Evaluation, str | None]:
    """``final`` without its ``thermal_lag`` (the others refitted) and the note saying
    why, when the lag is not resolvable: τ < τ_min, or its held-out gain is not
    ``margin`` above the largest of :data:`NULL_REPLAYS` readout replays without a
    lag (:func:`replay_lag_gain`); else ``final`` and None."""
    from gyrotherm.analysis._select import _refine_all

    tau = final.effects.get("thermal_lag")
    if tau is None:
        return final, None
    rest = {k: v for k, v in final.effects.items() if k != "thermal_lag"}
    if tau < limit.tau_min_s:
        why = (f"τ = {tau:.1f} s is below what the temperature readout can resolve "
               f"({limit.reason()}; hold {limit.hold_s:.2f} s, LSB crossing "
               f"{limit.lsb_crossing_s:.1f} s, smoother {limit.smoother_s:.1f} s)")
    else:
        gains = [replay_lag_gain(selector, final, readouts, limit, seed=seed + k)
                 for k in range(NULL_REPLAYS)]
        real, null = gains[0][0], max(g[1] for g in gains)
        if real >= (1.0 + margin) * null:
            return final, None
        why = (f"τ = {tau:.1f} s, held-out gain ×{real:.3f}, but replays of the runs' "
               f"readout (hold {limit.hold_s:.2f} s, LSB crossing {limit.lsb_crossing_s:.1f} s)"
               f" on a model without a lag already give a lag ×{null:.3f}: not "
               f"×{1.0 + margin:.2f} above what the readout alone produces")
    without = _refine_all(selector, selector.evaluate(rest))
    note = (f"thermal_lag not reported as a physical finding: {why}; held-out RMS "
            f"without it {without.heldout_rms_dps:.5f} vs {final.heldout_rms_dps:.5f} °/s")
    return without, note


NULL_REPLAYS = 2
"""Readout replays without a lag whose largest lag gain a real lag must beat."""
REPLAY_SUBSTEP_S = 0.1
"""Sub-sample spacing (s) of the replayed readout within each 1-s block."""
TRUTH_WINDOW_S = 121
"""Window (s, odd) of the zero-phase fit that gives the replay's smooth temperature."""


def _pseudo_truth(temperature_c: FloatArray, crossing_s: float) -> FloatArray:
    """A temperature history without the readout's steps: a zero-phase Savitzky–Golay
    fit (order 2) over max(121 s, 4 LSB crossings) — no lag added."""
    n = len(temperature_c)
    w = int(max(TRUTH_WINDOW_S, 4.0 * crossing_s)) | 1
    w = min(w, n - 1 if n % 2 == 0 else n)
    if w < 5:
        return temperature_c.copy()
    return np.asarray(savgol_filter(temperature_c, w, 2, mode="interp"), dtype=np.float64)


def _reread(
    time_s: FloatArray, truth_c: FloatArray, readout: Readout, rng: np.random.Generator
) -> FloatArray:
    """1-s block means of ``truth_c`` read as the sensor does: refreshed every
    period, white noise, quantised to the LSB, held in between."""
    sub = np.arange(0.0, float(time_s[-1]) + 1.0, REPLAY_SUBSTEP_S)
    period = max(readout.period_s, REPLAY_SUBSTEP_S)
    k = np.floor(sub / period).astype(np.int64)
    fresh_t = np.unique(k) * period
    values = np.interp(fresh_t, time_s, truth_c) + rng.standard_normal(len(fresh_t)) \
        * readout.noise_c
    if readout.lsb_c > 0:
        values = np.round(values / readout.lsb_c) * readout.lsb_c
    reading = values[np.searchsorted(np.unique(k), k)]
    block = np.floor(sub).astype(np.int64)
    means = np.bincount(block, weights=reading) / np.bincount(block)
    return np.asarray(means[: len(time_s)], dtype=np.float64)


def replay_lag_gain(
    selector: Selector, final: Evaluation, readouts: Sequence[Readout], limit: LagLimit,
    *, seed: int = 0,
) -> tuple[float, float]:
    """(real, null) held-out gains of the model's ``thermal_lag``.

    Real: held-out RMS of the model without the lag / with it. Null: the same on
    a replay of the runs in which no lag exists — the model without the lag,
    evaluated on a step-free temperature history (:func:`_pseudo_truth` of the
    features) plus white noise of the real residuals' spread, with the features
    recomputed from that history re-read through the runs' readout (period, LSB,
    noise: :func:`_reread`) and the same smoother. A lag the readout alone
    produces shows up in the null gain."""
    from dataclasses import replace

    from gyrotherm.analysis._prep import _smooth
    from gyrotherm.analysis._select import _refine_all

    rest = {k: v for k, v in final.effects.items() if k != "thermal_lag"}
    without = _refine_all(selector, selector.evaluate(rest))
    real = without.heldout_rms_dps / final.heldout_rms_dps
    readout = replace(readouts[0],
                      period_s=float(np.median([r.period_s for r in readouts])),
                      lsb_c=float(np.median([r.lsb_c for r in readouts])),
                      noise_c=float(np.median([r.noise_c for r in readouts])))
    rng = np.random.default_rng(seed)
    noise = float(np.sqrt(final.rss / final.n))
    tau = float(np.median([np.median(p.delta_t_c[p.rate_c_per_s != 0]
                                     / p.rate_c_per_s[p.rate_c_per_s != 0])
                           for p in selector.runs]))
    replayed = []
    for p in selector.runs:
        truth = _pseudo_truth(p.temperature_c, limit.lsb_crossing_s)
        rate_true = np.gradient(truth, p.time_s)
        true_run = replace(p, temperature_c=truth, rate_c_per_s=rate_true,
                           delta_t_c=tau * rate_true)
        _, x = design(true_run.time_s, truth, true_run.delta_t_c, selector.scaling,
                      without.effects)
        y = x @ without.coefficients + rng.standard_normal(len(p)) * noise
        temp, rate_c = _smooth(_reread(p.time_s, truth, readout, rng))
        replayed.append(replace(p, temperature_c=temp, rate_c_per_s=rate_c,
                                delta_t_c=tau * rate_c, rate_dps=y))
    null_sel = Selector(replayed, selector.scaling)
    null_without = _refine_all(null_sel, null_sel.evaluate(rest))
    null_with = _refine_all(null_sel, null_sel.evaluate({**rest, "thermal_lag": 0.0},
                                                        search="thermal_lag"))
    return real, null_without.heldout_rms_dps / null_with.heldout_rms_dps
