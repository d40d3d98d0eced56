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
exists. So the lag is compared with the lag :data:`NULL_REPLAYS` replays of the
runs without any lag produce through the same readout
(:func:`~._null_replay.replay_lag`). It is not resolvable when

* its held-out gain is not ``margin`` above the largest null gain, or
* the readout alone produces a lag that nearly passes the selection (null gain
  ≥ 1 + margin/2) at the same τ (within a factor :data:`SAME_TAU_FACTOR`): the
  data cannot tell that lag from the staircase's, whatever the gains (the
  replay's temperature is smoother than the device's, so its null gain is a
  lower bound; the τ the ripple selects is robust to that).

A ``hysteresis`` gets the same replay (:func:`drop_readout_hysteresis`: the
reading's code steps also switch the direction state): it must beat the null
gain by the margin.

An unexplained structure (:mod:`._unexplained`) gets it too
(:func:`readout_structure`, :func:`~._null_replay.replay_spline`): at a coarse
readout the T and ΔT terms misfit the staircase, and what they leave follows the
temperature profile, which every run repeats at about the same times since
power-on, so a spline in time (or T, ΔT) passes leave-one-run-out. The
structure must beat, by the margin, the largest gain a spline in its variable
buys on replays of the model without it; the effects already left out as not
resolvable are in the replays' generating model (not in the fitted one), so a
spline that only stands in for one of them is not a finding.

An unresolved lag, hysteresis or structure is left out of the model and
reported as a :class:`NotResolvable` verdict ("not resolvable at this readout")
with the reason, and in the notes. Effects selected beside a left-out one are
then checked again (:func:`~._select.prune`): one that no longer earns its place
without it is dropped.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from gyrotherm.analysis._null_replay import replay_lag, replay_spline
from gyrotherm.analysis._prep import Prepared, Readout
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._stats import RATE_THRESHOLD_C_PER_S
from gyrotherm.compensation._fit_offsets import BLOCK_S

if TYPE_CHECKING:
    from gyrotherm.analysis._unexplained import Unexplained

VERDICT = "not resolvable at this readout"
NULL_REPLAYS = 2
"""Readout replays without a lag whose largest lag gain a real lag must beat."""
SAME_TAU_FACTOR = 1.5
"""A lag within this factor of the τ the readout alone produces is not told apart from it."""
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


@dataclass(frozen=True)
class NotResolvable:
    """An effect the selection chose that the data cannot support at this readout (or,
    for ``effect = "shape:<name>"``, a finding whose shape it cannot resolve — a spline
    no better than the readout replays give, or a readout under which the check could not
    tell the form from its nearest alternative — the finding stays, without the note;
    :mod:`._shape_check`)."""

    effect: str
    params: Mapping[str, float]
    reason: str
    verdict: str = VERDICT
    """``"not resolvable at this readout"``, ``"not resolvable in these runs"`` where the
    runs' length, not the readout, is the limit, ``"a warm-up's second time constant"``
    for a drift a second warm-up exponential matches (both :mod:`._separable`), or
    ``"the hysteresis' first branch"`` for a warm-up that branch matches
    (:mod:`._first_branch`)."""

    def to_dict(self) -> dict[str, Any]:
        return {"effect": self.effect, "verdict": self.verdict, "params": dict(self.params),
                "reason": self.reason}


def drop_unresolved_lag(
    selector: Selector, final: Evaluation, limit: LagLimit, readouts: Sequence[Readout],
    *, margin: float = 0.10, seed: int = 0,
) -> tuple[Evaluation, NotResolvable | None]:
    """``final`` without its ``thermal_lag`` (the others refitted) and the verdict
    saying why, when the lag is not resolvable (module docstring); else ``final``
    and None."""
    from gyrotherm.analysis._select import _refine_all

    tau = final.effects.get("thermal_lag")
    if tau is None:
        return final, None
    rest = {k: v for k, v in final.effects.items() if k != "thermal_lag"}
    params = {"tau_s": float(tau)}
    if tau < limit.tau_min_s:
        why = (f"τ = {tau:.1f} s is below what the temperature readout can resolve "
               f"({limit.reason()}; hold {limit.hold_s:.2f} s, LSB crossing "
               f"{limit.lsb_crossing_s:.1f} s, smoother {limit.smoother_s:.1f} s)")
    else:
        rep = replay_lag(selector, final, readouts, limit.lsb_crossing_s, seed=seed,
                         replays=NULL_REPLAYS)
        params |= {"heldout_gain": rep.real_gain, "null_gain": rep.null_gain,
                   "null_tau_s": rep.null_tau}
        same_tau = 1.0 / SAME_TAU_FACTOR <= tau / rep.null_tau <= SAME_TAU_FACTOR
        readout = (f"hold {limit.hold_s:.2f} s, LSB crossing {limit.lsb_crossing_s:.1f} s on "
                   f"the ramps; null replays from the {rep.truth}")
        if rep.real_gain < (1.0 + margin) * rep.null_gain:
            why = (f"τ = {tau:.1f} s, held-out gain ×{rep.real_gain:.3f}, but replays of the "
                   f"runs' readout ({readout}) on a model without a lag already give a lag "
                   f"×{rep.null_gain:.3f}: not ×{1.0 + margin:.2f} above what the readout "
                   "alone produces")
        elif same_tau and rep.null_gain >= 1.0 + margin / 2.0:
            why = (f"τ = {tau:.1f} s, held-out gain ×{rep.real_gain:.3f}, but the readout "
                   f"alone ({readout}) produces a lag of τ = {rep.null_tau:.0f} s "
                   f"(gain ×{rep.null_gain:.3f}) in replays without one: the readout's "
                   f"quantisation ripple, smoothed by a lag of that τ, cannot be told apart "
                   f"from a lag within ×{SAME_TAU_FACTOR:g} of it")
        else:
            return final, None
    without = _refine_all(selector, selector.evaluate(rest))
    reason = (f"{why}; held-out RMS without it {without.heldout_rms_dps:.5f} vs "
              f"{final.heldout_rms_dps:.5f} °/s")
    return without, NotResolvable("thermal_lag", params, reason)


def drop_readout_hysteresis(
    selector: Selector, final: Evaluation, limit: LagLimit, readouts: Sequence[Readout],
    *, margin: float = 0.10, seed: int = 0,
) -> tuple[Evaluation, NotResolvable | None]:
    """``final`` without its ``hysteresis`` (the others refitted) and the verdict, when
    its held-out gain is not ``margin`` above what :data:`NULL_REPLAYS` readout replays
    without a hysteresis give one (:func:`~._null_replay.replay_lag` with
    ``effect="hysteresis"``: the quantised reading's steps also switch the direction
    state); else ``final`` and None."""
    from gyrotherm.analysis._select import _refine_all

    width = final.effects.get("hysteresis")
    if width is None:
        return final, None
    rep = replay_lag(selector, final, readouts, limit.lsb_crossing_s, seed=seed,
                     replays=NULL_REPLAYS, effect="hysteresis")
    if rep.real_gain >= (1.0 + margin) * rep.null_gain:
        return final, None
    rest = {k: v for k, v in final.effects.items() if k != "hysteresis"}
    without = _refine_all(selector, selector.evaluate(rest))
    reason = (f"held-out gain ×{rep.real_gain:.3f} (transition {width:.2f} °C), but replays of "
              f"the runs' readout (hold {limit.hold_s:.2f} s, LSB crossing "
              f"{limit.lsb_crossing_s:.1f} s on the ramps; from the {rep.truth}) on a model "
              f"without a hysteresis already give one ×{rep.null_gain:.3f}: not "
              f"×{1.0 + margin:.2f} above what the readout alone produces; held-out RMS "
              f"without it {without.heldout_rms_dps:.5f} vs {final.heldout_rms_dps:.5f} °/s")
    params = {"transition_c": float(width), "heldout_gain": rep.real_gain,
              "null_gain": rep.null_gain}
    return without, NotResolvable("hysteresis", params, reason)


def readout_structure(
    selector: Selector, effects: Mapping[str, float], u: Unexplained, limit: LagLimit,
    readouts: Sequence[Readout], *, margin: float = 0.10, seed: int = 0,
    unresolved: Mapping[str, float] | None = None, others: Sequence[Unexplained] = (),
) -> NotResolvable | None:
    """The verdict for the unexplained structure ``u`` found on top of the model
    ``effects`` when its held-out gain is not ``margin`` above what :data:`NULL_REPLAYS`
    readout replays of that model, with no structure, give a spline in the same
    variable (:func:`~._null_replay.replay_spline`): at a coarse readout the T and ΔT
    terms misfit the staircase, and what they leave follows the profile, which every
    run repeats at the same times since power-on; else None. ``unresolved``: the effects
    left out as not resolvable, in the replays' generating model
    (:func:`~._null_replay.replay_spline`). ``others``: the other structures found beside
    ``u``, in the replays' generating model and in the model fitted to them, as on the runs
    (:func:`~._null_replay.replay_spline`'s ``others``); the null is then the larger of the
    replays' with them and without them, so they can only make the verdict stricter."""
    gains, how = replay_spline(selector, dict(effects), readouts, limit.lsb_crossing_s,
                               u.variable, seed=seed, replays=NULL_REPLAYS,
                               unresolved=unresolved)
    if others:
        beside, _ = replay_spline(selector, dict(effects), readouts, limit.lsb_crossing_s,
                                  u.variable, seed=seed, replays=NULL_REPLAYS,
                                  unresolved=unresolved,
                                  others=[(w.variable, np.array(w.knots)) for w in others])
        gains = (*gains, *beside)
    null = max(gains)
    if u.gain >= (1.0 + margin) * null:
        return None
    reason = (f"a structure in {u.variable} over [{u.where[0]:.3g}, {u.where[1]:.3g}], "
              f"held-out gain ×{u.gain:.3f}, but replays of the runs' readout (hold "
              f"{limit.hold_s:.2f} s, LSB crossing {limit.lsb_crossing_s:.1f} s on the ramps; "
              f"from the {how}) on the model without it"
              + (f", {' and '.join(sorted(unresolved))} (left out by a verdict above) "
                 "included," if unresolved else "")
              + (f" (and with the structure{'s' if len(others) > 1 else ''} in "
                 f"{' and '.join(w.variable for w in others)} found beside it)"
                 if others else "")
              + " already give a spline in "
              f"{u.variable} ×{null:.3f}: not ×{1.0 + margin:.2f} above what the readout "
              "alone produces")
    return NotResolvable(f"unexplained:{u.variable}",
                         {"where_low": u.where[0], "where_high": u.where[1], "gain": u.gain,
                          "null_gain": null}, reason)
