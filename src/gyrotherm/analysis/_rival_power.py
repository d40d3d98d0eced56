"""Could this readout have told a structure's variable, or effect, from another? Replays.

:func:`~._unexplained.search_unexplained` lists beside a structure in v the variables w
whose spline does as well in its place on the runs (``not_told_from``). Two things it does
not see (round 15 of issue 19, on shapes-dev3 at the 1 °C / 1.3 s corner):

* **A preference the readout makes.** T and ΔT are estimates from a quantised, held
  reading (ΔT ∝ dT/dt of it); time since power-on is exact. A structure truly in ΔT, read
  through a 1 °C readout held 1.3 s, is fitted in an estimated ΔT that lags and smears the
  true one, so its spline on the runs may fail the entry criteria or lose to a spline in
  time that follows it through the chamber profile every run repeats (a saturating or
  \\|ΔT\\| response named only as a structure in time, ×1.15–1.2, on three devices).
* **A catalogued effect in its place.** A rate-dependent hysteresis read through that
  readout was named a structure in T (×1.23) where the catalogued hysteresis in the
  spline's place does as well held out (×1.002 apart); nothing said so.

So each candidate c (a variable w not found, or a catalogued effect e neither in the model
nor left out by a verdict) is put in the structure's place, on the same catalogued model
and other structures, and c is added to the structure's rivals when either

1. **on the runs** (catalogued effects; variables are listed so by the search): c passes
   the entry criteria against the model without the structure and is not beaten by
   ×(1 + margin) held out; or
2. **on readout replays with the structure in c**: c's structure exists on the step-free
   runs (:func:`~._null_replay.step_free_selector`: its spline, or e, passes the entry
   criteria there), and readout replays (:func:`~._null_replay._null_selectors`) of the
   model with it — w's spline in the step-free runs' own w, or e at its step-free
   parameter, at the size fitted there, the other structures in both as on the runs —
   give R_rep = held-out RMS with c / with v's spline (each fitted in the structure's
   place, knots and nonlinear parameters chosen on the replay) such that the runs'
   R = RMS with c / with v's spline is below (1 + margin)·max R_rep, over
   :data:`~._resolve.NULL_REPLAYS` replays of each noise kind (:data:`NOISES`; a claim that
   the two are told apart must hold on both, as the shape check's power does,
   :mod:`._shape_check`).

A variable goes to ``not_told_from``, an effect to ``effects_not_told_from``, each with its
held-out gain in the structure's place, and the evidence says which test listed it. It
adds a statement beside a structure already found and never a name, so no finding and no
null false alarm changes by it.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace

import numpy as np

from gyrotherm.analysis._effects import EFFECTS, TAU_GRIDS
from gyrotherm.analysis._null_replay import Noise, _null_selectors, step_free_selector
from gyrotherm.analysis._prep import Readout
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._unexplained import (
    VARIABLES,
    Unexplained,
    evaluate_with,
    knots_for,
    spline_knots,
)

NOISES: tuple[Noise, ...] = ("white", "coloured")
Splines = Sequence[tuple[str, np.ndarray]]


def in_place(sel: Selector, effects: Mapping[str, float], others: Splines, candidate: str,
             before: Evaluation | None = None) -> tuple[Evaluation, float | np.ndarray]:
    """The model ``effects`` + ``others`` with ``candidate`` added, a variable's spline (knots
    chosen as the search does) or a catalogued effect (its nonlinear parameter searched on
    its grid), and that spline's knots or the effect's parameter."""
    if candidate in VARIABLES:
        k = spline_knots(sel, effects, others, candidate, before)
        return evaluate_with(sel, effects, [*others, (candidate, k)]), k
    value = (float(sel.evaluate({**effects, candidate: 0.0}, search=candidate)
                   .effects[candidate]) if candidate in TAU_GRIDS else 0.0)
    return evaluate_with(sel, {**effects, candidate: value}, others), value


def _replayed(
    selector: Selector, effects: Mapping[str, float], readouts: Sequence[Readout],
    crossing_s: float, found: str, candidate: str, size: float | np.ndarray,
    others: Splines, *, seed: int, replays: int, unresolved: Mapping[str, float] | None,
    noise: Noise,
) -> list[float]:
    """R_rep on each replay generated with the structure in ``candidate`` (module
    docstring, test 2); ``size``: its knots (a variable) or step-free parameter (an
    effect)."""
    generating, splines = dict(effects), list(others)
    if candidate in VARIABLES:
        splines.append((candidate, np.asarray(size)))
    else:
        generating[candidate] = float(size)
    out = []
    for sel in _null_selectors(selector, generating, readouts, crossing_s, seed=seed,
                               replays=replays, unresolved=unresolved, noise=noise,
                               splines=splines):
        fitted = [(w, knots_for(sel.runs, w, len(k))) for w, k in others]
        base = evaluate_with(sel, effects, fitted)
        rms_found = in_place(sel, effects, fitted, found, base)[0].heldout_rms_dps
        rms_candidate = in_place(sel, effects, fitted, candidate, base)[0].heldout_rms_dps
        out.append(rms_candidate / rms_found)
    return out


def readout_rivals(
    selector: Selector, effects: Mapping[str, float], found: Sequence[Unexplained],
    variables: Sequence[str], readouts: Sequence[Readout], crossing_s: float, *,
    margin: float = 0.10, seed: int = 0, replays: int = 2,
    unresolved: Mapping[str, float] | None = None, excluded: Collection[str] = (),
) -> list[Unexplained]:
    """``found`` with their rivals extended (module docstring): ``variables``, those the
    search may name; ``effects``, the catalogued model the structures were found on;
    ``excluded``, effects a verdict left out (not rivals: the data cannot support them)."""
    from gyrotherm.analysis._select import enters

    if not found:
        return []
    n_runs = len(selector.runs)
    true_sel, _ = step_free_selector(selector, crossing_s)
    names = {u.variable for u in found}
    out = []
    for u in found:
        others = [(w.variable, np.array(w.knots)) for w in found if w is not u]
        before = evaluate_with(selector, effects, others)
        after = evaluate_with(selector, effects, [*others, (u.variable, np.array(u.knots))])
        true_before = evaluate_with(true_sel, effects, others)
        rivals: dict[str, dict[str, float]] = {"variable": {}, "effect": {}}
        reasons = []
        candidates = [*(w for w in variables if w not in names and w not in u.not_told_from),
                      *(e for e in EFFECTS if e not in effects and e not in excluded)]
        for c in candidates:
            kind = "variable" if c in VARIABLES else "effect"
            what = f"a structure in {c}" if kind == "variable" else f"a {c}"
            ev, _ = in_place(selector, effects, others, c, before)
            ratio = ev.heldout_rms_dps / after.heldout_rms_dps
            gain = before.heldout_rms_dps / ev.heldout_rms_dps
            if kind == "effect" and enters(before, ev, margin=margin, n_runs=n_runs) \
                    and ratio < 1.0 + margin:
                rivals[kind][c] = gain
                reasons.append(f"{what} does as well in its place (×{gain:.3f} held out, "
                               f"beaten by ×{ratio:.3f}): which it is is not resolvable in "
                               "these runs")
                continue
            true_ev, size = in_place(true_sel, effects, others, c, true_before)
            if not enters(true_before, true_ev, margin=margin, n_runs=n_runs):
                continue  # no such structure on the step-free runs to hypothesise
            replayed = {noise: max(_replayed(
                selector, effects, readouts, crossing_s, u.variable, c, size, others,
                seed=seed, replays=replays, unresolved=unresolved, noise=noise))
                for noise in NOISES}
            if all(ratio >= (1.0 + margin) * r for r in replayed.values()):
                continue
            rivals[kind][c] = gain
            reasons.append(
                f"{what} (×{gain:.3f} held out in its place) is beaten by ×{ratio:.3f} on "
                f"the runs, but on readout replays with {what} the spline in {u.variable} "
                "beats it by up to "
                + " and ".join(f"×{r:.3f} ({noise} noise)" for noise, r in replayed.items())
                + f": not ×{1.0 + margin:.2f} beyond what this readout does to {what}, so "
                "which it is is not resolvable at this readout")
        if reasons:
            u = replace(u, not_told_from={**u.not_told_from, **rivals["variable"]},
                        effects_not_told_from={**u.effects_not_told_from,
                                               **rivals["effect"]},
                        evidence=u.evidence + "; " + "; ".join(reasons))
        out.append(u)
    return out
