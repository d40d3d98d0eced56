"""Could this readout have told the structure's variable from another's? Readout replays.

:func:`~._unexplained.search_unexplained` lists beside a structure in v the variables w
whose spline does as well in its place on the runs (``not_told_from``). A w whose spline
passes the entry criteria in v's place but is beaten by more than ×(1 + margin) held out is
not listed there. Yet that preference for v may be the readout's doing: T and ΔT are
estimates from a quantised, held reading (ΔT ∝ dT/dt of it), time since power-on is exact.
A structure truly in ΔT, read through a 1 °C readout held 1.3 s, is fitted in an estimated
ΔT that lags and smears the true one; since every run repeats the chamber's profile at the
same times since power-on, a spline in time can follow it better than a spline in the
estimated ΔT (round 15 of issue 19: a saturating or \\|ΔT\\| response named only as a
structure in time, ×1.2–2.0, on four shapes-dev3 devices at that readout).

So for each such w the hypothesis "the structure is in w" is replayed: readout replays
(:func:`~._null_replay._null_selectors`, steps 1–3 of :mod:`._null_replay`) of the
diagnosis' model with a spline in the step-free runs' own w at the size it has on the runs
(the other structures found beside it in both, as on the runs). On each replay the spline
in v and the spline in w (knot counts chosen as the search does) are fitted in the
structure's place, and R_rep = held-out RMS with w's / with v's. On the runs,
R = held-out RMS with w's / with v's. The runs tell v from w only when
R ≥ (1 + margin)·max R_rep over :data:`~._resolve.NULL_REPLAYS` replays of each kind of
noise (white and coloured, :data:`~._null_replay.Noise`; a claim that the variables are told
apart must hold on both, as the shape check's power does, :mod:`._shape_check`); otherwise w
is added to ``not_told_from`` with its held-out gain, and the evidence says why. It adds a
statement beside a structure already found and never a name, so no finding and no null
false alarm changes by it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from gyrotherm.analysis._null_replay import Noise, _null_selectors, step_free_selector
from gyrotherm.analysis._prep import Readout
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._unexplained import (
    Unexplained,
    evaluate_with,
    knots_for,
    spline_knots,
)

NOISES: tuple[Noise, ...] = ("white", "coloured")


def _replayed_ratios(
    selector: Selector, effects: Mapping[str, float], readouts: Sequence[Readout],
    crossing_s: float, found: str, rival: tuple[str, np.ndarray],
    others: Sequence[tuple[str, np.ndarray]], *, seed: int, replays: int,
    unresolved: Mapping[str, float] | None, noise: Noise,
) -> list[float]:
    """R_rep on each replay generated with the structure in ``rival`` (module docstring)."""
    out = []
    for sel in _null_selectors(selector, dict(effects), readouts, crossing_s, seed=seed,
                               replays=replays, unresolved=unresolved, noise=noise,
                               splines=[*others, rival]):
        fitted = [(w, knots_for(sel.runs, w, len(k))) for w, k in others]
        base = evaluate_with(sel, effects, fitted)
        rms = {}
        for v in (found, rival[0]):
            k = spline_knots(sel, effects, fitted, v, base)
            rms[v] = evaluate_with(sel, effects, [*fitted, (v, k)]).heldout_rms_dps
        out.append(rms[rival[0]] / rms[found])
    return out


def readout_rivals(
    selector: Selector, effects: Mapping[str, float], found: Sequence[Unexplained],
    candidates: Sequence[str], readouts: Sequence[Readout], crossing_s: float, *,
    margin: float = 0.10, seed: int = 0, replays: int = 2,
    unresolved: Mapping[str, float] | None = None,
) -> list[Unexplained]:
    """``found`` with ``not_told_from`` extended by each variable of ``candidates`` (not
    itself found) that the runs do not tell from the structure's at this readout (module
    docstring); ``effects``: the catalogued model the structures were found on."""
    from gyrotherm.analysis._select import enters

    out: list[Unexplained] = []
    if not found:
        return out
    true_sel, _ = step_free_selector(selector, crossing_s)
    names = {u.variable for u in found}
    for u in found:
        others = [(w.variable, np.array(w.knots)) for w in found if w is not u]
        before = evaluate_with(selector, effects, others)
        after = evaluate_with(selector, effects, [*others, (u.variable, np.array(u.knots))])
        true_before = evaluate_with(true_sel, effects, others)
        added: dict[str, float] = {}
        reasons = []
        for w in candidates:
            if w in names or w in u.not_told_from:
                continue
            k = spline_knots(selector, effects, others, w, before)
            ev = evaluate_with(selector, effects, [*others, (w, k)])
            if not (enters(true_before, evaluate_with(true_sel, effects, [*others, (w, k)]),
                           margin=margin, n_runs=len(selector.runs))):
                continue  # no structure in the step-free w to hypothesise
            ratio = ev.heldout_rms_dps / after.heldout_rms_dps
            replayed = {noise: max(_replayed_ratios(
                selector, effects, readouts, crossing_s, u.variable, (w, k), others,
                seed=seed, replays=replays, unresolved=unresolved, noise=noise))
                for noise in NOISES}
            if all(ratio >= (1.0 + margin) * r for r in replayed.values()):
                continue
            added[w] = before.heldout_rms_dps / ev.heldout_rms_dps
            reasons.append(
                f"a structure in {w} (×{added[w]:.3f} held out in its place) is beaten by "
                f"×{ratio:.3f} on the runs, but on readout replays with the structure in {w} "
                f"the spline in {u.variable} beats it by up to "
                + " and ".join(f"×{r:.3f} ({noise} noise)" for noise, r in replayed.items())
                + f": not ×{1.0 + margin:.2f} beyond what this readout does to a structure "
                f"in {w}, so which variable it is in is not resolvable at this readout")
        if added:
            u = replace(u, not_told_from={**u.not_told_from, **added},
                        evidence=u.evidence + "; " + "; ".join(reasons))
        out.append(u)
    return out
