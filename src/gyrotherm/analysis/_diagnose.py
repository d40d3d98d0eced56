"""``diagnose``: which physical effect do the paper model and the simulator miss?

1. Prepare the runs (:mod:`._prep`), fit the baseline (paper model, one
   offset per run) and score it leave-one-run-out (:mod:`._select`).
2. Calibrate gyrotherm's simulator to the runs, replay their temperature
   histories several times (noise seeds) with the baseline and the extended
   model, and score each residual statistic of the measured output against
   the replays' spread: z = (measured − replay mean)/replay std, sorted by |z|,
   significant beyond a threshold set for the number of replays; statistics
   the runs cannot show are listed in ``notes`` (:mod:`._compare`,
   :mod:`.simcal._simulate`, :mod:`._stats`).
3. Select effects (forward selection with held-out and penalised criteria);
   leave out a ``thermal_lag`` the temperature readout cannot resolve
   (:mod:`._resolve`: below τ_min, or no better than on readout replays
   without a lag), likewise a hysteresis, and a drift next to a warm-up that
   has not decayed (:mod:`._separable`) — each a ``not_resolvable`` verdict with
   its reason, not a finding; the effects selected beside one are checked again
   (:func:`~._select.prune`); test residual structure no catalogued effect
   explains (:mod:`._unexplained`: a spline in T, ΔT or time since power-on,
   reported as an ``unexplained`` finding, not part of the extended model; one
   another variable's spline does as well in its place names it, ``not_told_from``, and
   so does a variable or catalogued effect the runs prefer it to no more than this readout
   would if the structure were in it (:mod:`._rival_power`); one
   no better than readout replays without it give is a verdict, :mod:`._resolve`, and
   one sharper than the readout can place gets a note saying so, :mod:`._resolution`; a
   catalogued finding whose "shape differs" note the readout alone would produce keeps its
   name without the note and gets a ``shape:<effect>`` verdict, :mod:`._shape_check`); state
   the detection floor, the held-out gain below which a structure in each variable is not
   resolvable at this readout (:mod:`._floor`); name beside each finding the catalogued
   effects that do as well alone held out, ``not_told_from`` (:mod:`._catalogued_rivals`);
   refit the
   extended model, replay it through the extended simulator, and report
   (schema ``gyrotherm.diagnosis/1``).
4. Optionally (:func:`export_calibration`) write the chosen extended model as a
   calibration file for every axis the runs share.

``gain`` = baseline held-out RMS / model held-out RMS. A finding's
``heldout_rms_dps`` and ``gain`` are those of the baseline plus that effect
alone; its ``params`` come from the extended (joint) fit. Held-out RMS is on
1-s blocks with the left-out run's own mean residual (its switch-on offset)
removed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.analysis._catalogued_rivals import catalogued_rivals, rival_text
from gyrotherm.analysis._compare import (
    DEFAULT_REPLAYS,
    MIN_REPLAYS,
    SimulationComparison,
    compare_simulation,
)
from gyrotherm.analysis._effects import EFFECTS, ExtendedModel
from gyrotherm.analysis._first_branch import drop_warmup_like_first_branch
from gyrotherm.analysis._floor import Floor, detection_floors
from gyrotherm.analysis._null_replay import Columns, Noise, replay_shape
from gyrotherm.analysis._prep import (
    DEFAULT_TAU_S,
    Prepared,
    characterise,
    estimator_for,
    fit_tau,
    prepare,
    with_tau,
)
from gyrotherm.analysis._rate_width import VARIABLE as TIMING_VARIABLE
from gyrotherm.analysis._rate_width import rate_width
from gyrotherm.analysis._resolution import Resolution, placement
from gyrotherm.analysis._resolve import (
    NULL_REPLAYS,
    NotResolvable,
    drop_readout_hysteresis,
    drop_unresolved_lag,
    lag_limit,
    readout_structure,
)
from gyrotherm.analysis._rival_power import readout_rivals
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._select import Selection, prune, select
from gyrotherm.analysis._separable import (
    drop_hysteresis_like_gradient,
    drop_unsupported_drift,
)
from gyrotherm.analysis._shape_check import shape_notes
from gyrotherm.analysis._to_calibration import EffectsFit, fit_effects
from gyrotherm.analysis._unexplained import VARIABLES, Unexplained, search_unexplained
from gyrotherm.codecs import AXES, Run
from gyrotherm.compensation import Scaling

SCHEMA = "gyrotherm.diagnosis/1"


@dataclass(frozen=True)
class Finding:
    effect: str
    params: Mapping[str, float]
    evidence: str
    heldout_rms_dps: float
    gain: float
    shape: str = ""
    """Non-empty when the data's structure in this effect's variable is not the
    catalogued form (:mod:`._shape_check`): the note saying how the shape differs."""
    not_told_from: Mapping[str, float] = field(default_factory=dict)
    """Other catalogued effects that do as well alone held out (:mod:`._catalogued_rivals`,
    effect → its held-out gain alone): which of them this is is not resolvable at this
    readout."""

    @property
    def rivals(self) -> str:
        """``not_told_from``'s effects, "cubic or hysteresis" ("" when none)."""
        return " or ".join(sorted(self.not_told_from))

    def to_dict(self) -> dict[str, Any]:
        out = {"effect": self.effect, "params": dict(self.params), "evidence": self.evidence,
               "heldout_rms_dps": self.heldout_rms_dps, "gain": self.gain}
        if self.shape:
            out["shape_differs"] = self.shape
        if self.not_told_from:
            out["not_told_from"] = dict(self.not_told_from)
        return out


@dataclass(frozen=True)
class Diagnosis:
    """Everything the diagnosis found, with what the report needs to plot it."""

    axis: str
    prepared: tuple[Prepared, ...]
    baseline: ExtendedModel
    extended: ExtendedModel
    selection: Selection
    findings: tuple[Finding, ...]
    baseline_heldout_rms_dps: float
    extended_heldout_rms_dps: float
    residuals: tuple[np.ndarray, ...]
    extended_residuals: tuple[np.ndarray, ...]
    heldout_baseline: tuple[float, ...]
    heldout_extended: tuple[float, ...]
    tau_s: float
    tau_from_chamber: bool
    simulation: SimulationComparison | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    unexplained: tuple[Unexplained, ...] = field(default_factory=tuple)
    """Significant residual structure no catalogued effect explains (:mod:`._unexplained`);
    listed after the findings in ``to_dict``, not part of ``extended``."""
    not_resolvable: tuple[NotResolvable, ...] = field(default_factory=tuple)
    """Effects the selection chose that the data cannot support at this readout
    (:mod:`._resolve`): left out of ``extended``, named with the reason instead. A
    ``shape:<effect>`` entry is different: the effect stays a finding (in ``extended``);
    only the note that its shape differs is not supported (:mod:`._shape_check`)."""
    floors: tuple[Floor, ...] = field(default_factory=tuple)
    """The detection floor in each variable (:mod:`._floor`): a structure gaining less
    than its ``gain`` held out over ``extended`` is not resolvable at this readout."""

    @property
    def gain(self) -> float:
        return self.baseline_heldout_rms_dps / self.extended_heldout_rms_dps

    def to_dict(self) -> dict[str, Any]:
        sim = self.simulation
        return {
            "schema": SCHEMA,
            "axis": self.axis,
            "runs": [p.name for p in self.prepared],
            "baseline": {"model": "paper", "heldout_rms_dps": self.baseline_heldout_rms_dps},
            "findings": [f.to_dict() for f in self.findings]
            + [u.to_dict() for u in self.unexplained],
            "extended": {
                "model": self.extended.name,
                "effects": [e for e in EFFECTS if e in self.extended.effects],
                "heldout_rms_dps": self.extended_heldout_rms_dps,
                "gain": self.gain,
            },
            "not_resolvable": [v.to_dict() for v in self.not_resolvable],
            "detection_floor": [f.to_dict() for f in self.floors],
            "simulation": sim.to_dict() if sim else {"mismatch": [], "calibration": None},
            "notes": list(self.notes),
        }


def _default_axis(runs: Sequence[Run]) -> str:
    for a in AXES:
        if a in runs[0].rates_dps:
            return a
    raise CalibrationError(f"{runs[0].source}: run {runs[0].name!r} has no rate column")


def _check(runs: Sequence[Prepared]) -> None:
    spans = [float(np.ptp(p.temperature_c)) if len(p) else 0.0 for p in runs]
    if sum(s >= 1.0 for s in spans) < 2:
        listing = ", ".join(f"{p.name}: {s:.2f} °C" for p, s in zip(runs, spans, strict=True))
        raise CalibrationError(
            "diagnosis needs at least 2 runs whose temperature changes by ≥ 1 °C within the "
            f"run (spans {listing}): "
            "with one offset per run, a temperature model is fitted on changes within runs"
        )


def _residuals(sel: Selector, ev: Evaluation) -> list[np.ndarray]:
    return sel.residuals(ev.effects, ev.coefficients)


def _evidence(name: str, selection: Selection, final_drop_gain: float | None, n_runs: int) -> str:
    alone = selection.alone[name]
    base = selection.baseline
    improved = int(np.sum(alone.heldout_sse < base.heldout_sse))
    n_eff = min(base.n_eff, alone.n_eff)
    dbic = alone.bic(n_eff) - base.bic(n_eff)
    text = (f"alone: held-out RMS {base.heldout_rms_dps:.5f} → {alone.heldout_rms_dps:.5f} °/s, "
            f"better on {improved}/{n_runs} left-out runs; ΔBIC_eff = {dbic:.1f} "
            f"(n_eff = {n_eff:.0f})")
    if final_drop_gain is not None:
        text += f"; in the extended model it buys a further ×{final_drop_gain:.3f}"
    return text


def diagnose(
    runs: Sequence[Run],
    *,
    axis: str | None = None,
    margin: float = 0.10,
    simulate: bool = True,
    seed: int = 0,
    replays: int = DEFAULT_REPLAYS,
    features: str = "smooth",
    progress: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Diagnose ``runs`` (≥ 2, one device) on ``axis`` (default: first rate column).

    ``replays`` (≥ 2): how many times the simulator replays the runs, per model,
    with seeds ``seed + 100 000·k``; their spread gives each statistic's z-score
    (:mod:`._compare`)."""
    say = progress or (lambda _msg: None)
    if simulate and replays < MIN_REPLAYS:
        raise ConfigError(f"diagnose: replays = {replays!r} is below {MIN_REPLAYS}: the "
                          "replays' spread needs at least 2 of them")
    if len(runs) < 2:
        raise CalibrationError(
            f"diagnosis needs at least 2 runs (leave-one-run-out), got {len(runs)}")
    axis = axis or _default_axis(runs)
    for r in runs:
        if axis not in r.rates_dps:
            raise CalibrationError(
                f"{r.source}: run {r.name!r} has no rate axis {axis!r} (has {list(r.axes)})")
    readouts = [characterise(r, axis) for r in runs]
    est = estimator_for(readouts)
    say(f"preparing {len(runs)} runs (axis {axis})")
    prepared = [prepare(r, axis, est, features=features) for r in runs]
    tau_fit = fit_tau(prepared)
    tau_s, heating = (tau_fit if tau_fit else (DEFAULT_TAU_S, 0.0))
    prepared = [with_tau(p, tau_s) for p in prepared]
    _check(prepared)
    notes = [] if tau_fit else [
        "no chamber_c column: τ fixed at 120 s (ΔT coefficients scale with 1/τ)"]
    scaling = Scaling.from_data(np.concatenate([p.temperature_c for p in prepared]),
                                np.concatenate([p.delta_t_c for p in prepared]))
    selector = Selector(prepared, scaling)
    say("selecting effects (leave-one-run-out)")
    selection = select(selector, margin=margin, progress=say)
    base_ev, final_ev = selection.baseline, selection.final
    limit = lag_limit(readouts, prepared, features=features)
    selected = dict(final_ev.effects)
    final_ev, lag_verdict = drop_unresolved_lag(
        selector, final_ev, limit, readouts, margin=margin, seed=seed)
    final_ev, hyst_verdict = drop_readout_hysteresis(
        selector, final_ev, limit, readouts, margin=margin, seed=seed)
    final_ev, drift_verdict, warmup_note = drop_unsupported_drift(selector, final_ev)
    if hyst_verdict is None:
        final_ev, hyst_verdict = drop_hysteresis_like_gradient(selector, final_ev,
                                                               margin=margin)
    final_ev, branch_verdict = drop_warmup_like_first_branch(selector, final_ev)
    verdicts = tuple(v for v in (lag_verdict, hyst_verdict, drift_verdict, branch_verdict)
                     if v)
    for v in verdicts:
        notes.append(f"{v.effect} not reported as a physical finding ({v.verdict}): {v.reason}")
        say(notes[-1])
    if verdicts:  # what was selected beside a left-out effect must still earn its place
        final_ev, pruned = prune(selector, final_ev, margin=margin)
        if pruned:
            notes.append(f"dropped {', '.join(pruned)}: without "
                         f"{', '.join(v.effect for v in verdicts)} it no longer earns its "
                         "place (selected beside it)")
            say(notes[-1])
    say("testing residual structure no catalogued effect explains")
    resolution = Resolution(lsb_c=float(np.median([r.lsb_c for r in readouts])), tau_s=tau_s,
                            hold_s=float(np.median([r.period_s for r in readouts])))
    variables = list(VARIABLES)
    # what the verdicts left out stays in the null the structures must beat
    unresolved = {v.effect: selected[v.effect] for v in verdicts if v.effect in selected}
    while True:  # a structure the readout alone gives: a verdict, and search without it
        search = search_unexplained(selector, final_ev, margin=margin, variables=variables)
        too_fine = [v for v in (readout_structure(  # more than the readout alone gives?
            selector, search.catalogued.effects, u, limit, readouts, margin=margin,
            seed=seed, unresolved=unresolved,
            others=[w for w in search.unexplained if w is not u])
            for u in search.unexplained) if v]
        if not too_fine:
            break
        if len(search.unexplained) > 1:  # each one's null holds the others: leave out the
            # one furthest below its null, then search again without it
            too_fine = [min(too_fine, key=lambda v: v.params["gain"] / v.params["null_gain"])]
        for v in too_fine:
            verdicts = (*verdicts, v)
            variables.remove(v.effect.split(":", 1)[1])
            notes.append(f"{v.effect} not reported as a finding ({v.verdict}): {v.reason}")
            say(notes[-1])
    final_ev = search.catalogued
    found = list(search.unexplained)
    timing = rate_width(selector, final_ev.effects,
                        [(u.variable, np.array(u.knots)) for u in found], margin=margin)
    if timing is not None:  # the structure in time is the hysteresis' own timing
        found = [u for u in found if u.variable != TIMING_VARIABLE]
        notes.append(f"unexplained:{TIMING_VARIABLE} not reported: a hysteresis whose "
                     "width grows with the rate does as well in its place (hysteresis' note)")
        say(notes[-1])
    # a variable the runs prefer to another's only as this readout would: not told apart
    found = readout_rivals(selector, final_ev.effects, found, variables, readouts,
                           limit.lsb_crossing_s, margin=margin, seed=seed,
                           replays=NULL_REPLAYS, unresolved=unresolved,
                           excluded=[v.effect for v in verdicts if v.effect in EFFECTS])
    unexplained = []
    for u in found:  # real, but sharper than the readout can place
        where_note = placement(u, resolution)
        if where_note:
            u = replace(u, evidence=f"{u.evidence}; {where_note}")
            notes.append(f"unexplained:{u.variable}: {where_note}")
            say(notes[-1])
        if u.not_told_from:  # another variable's spline does as well in its place
            notes.append(f"unexplained:{u.variable}: which variable it is in is not "
                         "resolvable at this readout: a structure in "
                         f"{u.rivals} does as well held out, or as well as this readout "
                         "lets it")
            say(notes[-1])
        if u.effects_not_told_from:  # a catalogued effect in its place
            notes.append(f"unexplained:{u.variable}: whether it is a catalogued effect is "
                         f"not resolvable at this readout: {u.effect_rivals} in its place "
                         "does as well held out, or as well as this readout lets it")
            say(notes[-1])
        unexplained.append(u)
    if search.dropped:
        notes.append(f"dropped {', '.join(search.dropped)}: with the unexplained correction it "
                     "no longer earns its place (it stood in for that structure)")
    say("measuring the detection floor (readout replays without a structure)")
    floors = detection_floors(selector, final_ev.effects, readouts, limit.lsb_crossing_s,
                              final_ev.heldout_rms_dps, VARIABLES, margin=margin, seed=seed,
                              replays=NULL_REPLAYS, unresolved=unresolved)
    baseline = selector.model(base_ev)
    extended = selector.model(final_ev)
    params = extended.params()
    findings = []
    rivals = catalogued_rivals(base_ev, selection.alone, list(final_ev.effects),
                               [v.effect for v in verdicts], n_runs=len(runs), margin=margin)
    for name in final_ev.effects:
        rest = {k: v for k, v in final_ev.effects.items() if k != name}
        drop = selector.evaluate(rest) if rest else None
        drop_gain = drop.heldout_rms_dps / final_ev.heldout_rms_dps if drop else None
        alone = selection.alone[name]
        rival = rivals.get(name, {})
        findings.append(Finding(
            effect=name,
            params=params[name],
            evidence=_evidence(name, selection, drop_gain, len(runs)) + rival_text(rival),
            heldout_rms_dps=alone.heldout_rms_dps,
            gain=base_ev.heldout_rms_dps / alone.heldout_rms_dps,
            not_told_from=rival,
        ))
        if rival:
            notes.append(f"{name}: which catalogued effect it is is not resolvable at this "
                         f"readout: {findings[-1].rivals} does as well alone held out")
            say(notes[-1])
    def shape_power(name: str, variable: str, n_knots: int, alternative: Columns | None,
                    noise: Noise = "white", /) -> tuple[float, ...]:
        return replay_shape(selector, dict(final_ev.effects), readouts, limit.lsb_crossing_s,
                            name, variable, n_knots,
                            splines=[(u.variable, len(u.knots)) for u in unexplained],
                            unresolved=unresolved, seed=seed, replays=NULL_REPLAYS,
                            alternative=alternative, noise=noise)

    def shape_replay(name: str, variable: str, n_knots: int, noise: Noise = "white",
                     /) -> tuple[float, ...]:
        return shape_power(name, variable, n_knots, None, noise)

    checked = shape_notes(selector, final_ev.effects,
                          [(u.variable, np.array(u.knots)) for u in unexplained],
                          replay=shape_replay, power=shape_power)
    shapes = dict(checked.differs)
    if timing is not None:
        shapes["hysteresis"] = "; ".join(t for t in (timing.note(), shapes.get("hysteresis"))
                                         if t)
    for name, verdict in checked.unresolved.items():
        if name == "warmup" and warmup_note:  # the second warm-up's own held-out test
            continue                          # says how the shape differs
        # the effect stays in the model; only its shape is not supported
        verdicts = (*verdicts, verdict)
        notes.append(f"{name}: its shape is not resolvable at this readout: {verdict.reason}")
        say(notes[-1])
    if warmup_note and "warmup" in final_ev.effects:
        shapes["warmup"] = "; ".join(t for t in (shapes.get("warmup"), warmup_note) if t)
    findings = [replace(f, shape=shapes[f.effect]) if f.effect in shapes else f
                for f in findings]
    notes += [f"{name}: {text}" for name, text in shapes.items()]
    findings.sort(key=lambda f: -f.gain)
    resid = _residuals(selector, base_ev)
    ext_resid = _residuals(selector, final_ev)
    held_b = tuple(math.sqrt(s / n) for s, n in zip(base_ev.heldout_sse, base_ev.heldout_n,
                                                   strict=True))
    held_e = tuple(math.sqrt(s / n) for s, n in zip(final_ev.heldout_sse, final_ev.heldout_n,
                                                   strict=True))
    diagnosis = Diagnosis(
        axis=axis, prepared=tuple(prepared), baseline=baseline, extended=extended,
        selection=selection, findings=tuple(findings),
        baseline_heldout_rms_dps=base_ev.heldout_rms_dps,
        extended_heldout_rms_dps=final_ev.heldout_rms_dps,
        residuals=tuple(resid), extended_residuals=tuple(ext_resid),
        heldout_baseline=held_b, heldout_extended=held_e,
        tau_s=tau_s, tau_from_chamber=tau_fit is not None, notes=tuple(notes),
        unexplained=tuple(unexplained), not_resolvable=verdicts, floors=floors,
    )
    if not simulate:
        return diagnosis
    say(f"calibrating the simulator and replaying the runs {replays}× per model")
    sim = compare_simulation(runs, readouts, diagnosis, est_tau=tau_s, self_heating_c=heating,
                             seed=seed, replays=replays, features=features)
    return replace(diagnosis, simulation=sim, notes=(*diagnosis.notes, *sim.notes))



def export_calibration(
    runs: Sequence[Run],
    diagnosis: Diagnosis,
    *,
    margin: float = 0.10,
    features: str = "smooth",
    progress: Callable[[str], None] | None = None,
) -> EffectsFit:
    """A calibration of the chosen extended model on every axis all ``runs`` share.

    Effects are chosen per axis: the diagnosis' for its axis, the same forward
    selection (``margin``, the diagnosis' ``features``) on every other axis;
    nothing found gives the paper model on that axis. Coefficients and
    nonlinear parameters are then refitted on every axis with the causal
    estimator the calibration stores (:func:`~gyrotherm.analysis._to_calibration.fit_effects`:
    the features the vehicle computes; the diagnosis' own ΔT comes from a
    zero-phase smoother the vehicle cannot run). τ is the diagnosis'.
    """
    from dataclasses import replace

    from gyrotherm.compensation import features as estimate

    say = progress or (lambda _msg: None)
    axes = [a for a in AXES if all(a in r.rates_dps for r in runs)]
    est = replace(estimator_for([characterise(r, diagnosis.axis) for r in runs]),
                  tau_s=diagnosis.tau_s)
    chosen: dict[str, tuple[str, ...]] = {}
    record: dict[str, dict[str, Any]] = {}
    for axis in axes:
        if axis == diagnosis.axis:
            chosen[axis] = tuple(e for e in EFFECTS if e in diagnosis.extended.effects)
            record[axis] = {"effects": list(chosen[axis]), "selected_by": "diagnosis",
                            "gain": diagnosis.gain}
            continue
        say(f"selecting effects on axis {axis}")
        prepared = [prepare(r, axis, est, features=features) for r in runs]
        scaling = Scaling.from_data(np.concatenate([p.temperature_c for p in prepared]),
                                    np.concatenate([p.delta_t_c for p in prepared]))
        selection = select(Selector(prepared, scaling), margin=margin, progress=say)
        chosen[axis] = tuple(e for e in EFFECTS if e in selection.final.effects)
        record[axis] = {"effects": list(chosen[axis]), "selected_by": "forward selection",
                        "gain": selection.baseline.heldout_rms_dps
                        / selection.final.heldout_rms_dps}
    say("fitting the calibration on the estimator's features (" + ", ".join(
        f"{a}: {'+'.join(('paper', *chosen[a]))}" for a in axes) + ")")
    provenance = {"diagnosis": {
        "schema": SCHEMA, "axis": diagnosis.axis, "features": features, "margin": margin,
        "tau_s": diagnosis.tau_s, "tau_from_chamber": diagnosis.tau_from_chamber,
        "axes": record,
        "deployed": [u.to_dict() for u in diagnosis.unexplained[:1]],
        "not_deployed": [u.to_dict() for u in diagnosis.unexplained[1:]],
        "runs": [{"name": r.name, "source": r.source, "sha256": r.sha256} for r in runs]}}
    # the first unexplained structure (the largest gain) becomes the axis' correction
    if diagnosis.unexplained and (diagnosis.unexplained[0].not_told_from
                                  or diagnosis.unexplained[0].effects_not_told_from):
        u = diagnosis.unexplained[0]
        say(f"the correction in {u.variable} is not told apart from {u.alike} in these runs "
            f"(they move together): on a vehicle where they do not, it may not hold; runs "
            f"with other temperature profiles would tell them apart")
    corrections = ({diagnosis.axis: diagnosis.unexplained[0].variable}
                   if diagnosis.unexplained else None)
    knots = ({diagnosis.axis: len(diagnosis.unexplained[0].knots)}
             if diagnosis.unexplained else None)
    return fit_effects([estimate(r, est) for r in runs], chosen, estimator=est,
                       provenance=provenance, corrections=corrections, correction_knots=knots)
