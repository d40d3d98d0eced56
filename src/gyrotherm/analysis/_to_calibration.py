"""Extended models as calibration files: the converter and named-effect fits (what
``gyrotherm diagnose --calibration`` writes: a diagnosis turned into a gyrotherm
calibration). Not the autopilot export: ``gyrotherm export``
(:mod:`gyrotherm.cli._export`, :mod:`gyrotherm.compensation._autopilot`) writes
ArduPilot/PX4 parameters from a calibration.

:func:`calibration_from_models` turns fitted :class:`ExtendedModel`\\ s, one per
axis, into a :class:`~gyrotherm.compensation.Calibration`: base coefficients
(T², T, ΔT, T·ΔT, 1: the paper model, the common intercept last) plus the
axis' effects (:meth:`ExtendedModel.online_effects`), written as a version-2
file when any axis has effects.

:func:`fit_effects` fits named effects per axis on the features the vehicle
computes: the calibration's estimator run row by row over each run
(:func:`gyrotherm.compensation.features`, as ``gyrotherm fit`` and the daemon
do), averaged over 1-s blocks of time since power-on, one offset per run; the
nonlinear parameters (time constants, the hysteresis transition) are searched
as the diagnosis does (:meth:`Selector.evaluate` with ``search``), per axis.
The calibrated range is that of the per-row estimates.

``corrections`` (axis → variable) adds the diagnosis' ``unexplained`` structure as the
axis' deployable ``correction`` (:mod:`gyrotherm.compensation._correction`): on the same
1-s blocks of the vehicle's features, as many knots as the diagnosis' spline has (its
count chosen by BIC_eff, :func:`~._unexplained.spline_knots`) over the blocks' range of
the variable (:func:`~._unexplained.knots_for`), values fitted to the fitted model's residuals
(:func:`~._unexplained.two_stage`: the base coefficients and effects stay as fitted),
and its leave-one-run-out gain recorded in the provenance.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyrotherm import __version__
from gyrotherm._errors import CalibrationError
from gyrotherm.analysis._effects import (
    DIRECTION_WIDTH_C,
    EFFECTS,
    TAU_GRIDS,
    ExtendedModel,
    direction_state,
)
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._unexplained import N_KNOTS, evaluate_with, knots_for, two_stage
from gyrotherm.compensation import (
    Calibration,
    RunFeatures,
    ValidRange,
    default_scaling,
    get_model,
    score,
)
from gyrotherm.compensation._correction import Correction
from gyrotherm.compensation._fit_offsets import block_mean
from gyrotherm.compensation._fit_offsets import blocks as second_blocks
from gyrotherm.estimators import EstimatorConfig


def calibration_from_models(
    models: Mapping[str, ExtendedModel],
    *,
    estimator: EstimatorConfig,
    valid_range: ValidRange,
    t_on_max_s: float | None,
    provenance: Mapping[str, Any],
) -> Calibration:
    """One calibration from per-axis models sharing one scaling; a drift's ramp is
    limited to ``t_on_max_s`` (the longest calibration run)."""
    scalings = {m.scaling for m in models.values()}
    if len(scalings) != 1:
        raise CalibrationError(f"models of axes {sorted(models)} do not share one scaling")
    effects = {a: m.online_effects(t_on_max_s=t_on_max_s) for a, m in models.items()}
    return Calibration(
        model=get_model("paper"),
        scaling=scalings.pop(),
        coefficients={a: m.base_coefficients() for a, m in models.items()},
        valid_range=valid_range,
        estimator=estimator,
        provenance=dict(provenance),
        effects={a: e for a, e in effects.items() if e.names},
    )


def blocks(run: RunFeatures, axis: str, tau_s: float) -> Prepared:
    """Per-row estimator features of ``run`` averaged over 1-s blocks (one axis)."""
    if axis not in run.rates_dps:
        raise CalibrationError(f"{run.source}: run {run.name!r} has no rate axis {axis!r}")
    inverse, counts = second_blocks(run.time_s)
    temp = block_mean(run.temperature_c, inverse, counts)
    dtemp = block_mean(run.delta_t_c, inverse, counts)
    return Prepared(name=run.name, time_s=block_mean(run.time_s, inverse, counts),
                    temperature_c=temp, rate_c_per_s=dtemp / tau_s, delta_t_c=dtemp,
                    chamber_c=None, rate_dps=block_mean(run.rates_dps[axis], inverse, counts),
                    counts=counts, direction=direction_state(temp, DIRECTION_WIDTH_C))


@dataclass(frozen=True)
class EffectsFit:
    """:func:`fit_effects`' result: the calibration and, per axis, the fitted model and
    the leave-one-run-out RMS (1-s blocks) of the paper model and of the fitted one."""

    calibration: Calibration
    models: Mapping[str, ExtendedModel]
    baseline_heldout_rms_dps: Mapping[str, float]
    heldout_rms_dps: Mapping[str, float]


def correction_for(selector: Selector, ev: Evaluation, variable: str,
                   *, source: str, n_knots: int = N_KNOTS) -> tuple[Correction, dict[str, Any]]:
    """The ``correction`` in ``variable`` (``n_knots`` knots) on top of the fitted model
    ``ev`` and its record (leave-one-run-out RMS without and with it, the spline fitted
    jointly)."""
    knots = knots_for(selector.runs, variable, n_knots)
    values = two_stage(selector.runs, selector.residuals(ev.effects, ev.coefficients),
                       variable, knots)
    before = evaluate_with(selector, ev.effects, [])
    after = evaluate_with(selector, ev.effects, [(variable, knots)])
    corr = Correction(variable, tuple(float(k) for k in knots),
                      tuple(float(v) for v in values), source=source)
    return corr, {"variable": variable, "knots": len(knots),
                  "range": [float(knots[0]), float(knots[-1])],
                  "heldout_rms_dps": after.heldout_rms_dps,
                  "baseline_heldout_rms_dps": before.heldout_rms_dps,
                  "gain": before.heldout_rms_dps / after.heldout_rms_dps}


def fit_effects(
    runs: Sequence[RunFeatures],
    effects: Mapping[str, Sequence[str]],
    *,
    estimator: EstimatorConfig,
    provenance: Mapping[str, Any] | None = None,
    corrections: Mapping[str, str] | None = None,
    correction_knots: Mapping[str, int] | None = None,
) -> EffectsFit:
    """Fit the paper model plus ``effects[axis]`` on every axis of ``effects`` (features
    made with ``estimator``; ≥ 2 runs: the search scores leave-one-run-out), and the
    ``corrections`` (axis → variable; module docstring) with ``correction_knots`` (axis →
    knot count, the diagnosis' spline's; default :data:`~._unexplained.N_KNOTS`)."""
    if len(runs) < 2:
        raise CalibrationError(f"fitting effects needs at least 2 runs (the nonlinear "
                               f"parameters are searched leave-one-run-out), got {len(runs)}")
    for axis, names in effects.items():
        unknown = sorted(set(names) - set(EFFECTS))
        if unknown:
            raise CalibrationError(f"axis {axis}: unknown effects {unknown}; known: "
                                   f"{', '.join(EFFECTS)}")
    scaling = default_scaling(runs)
    models: dict[str, ExtendedModel] = {}
    base_rms: dict[str, float] = {}
    rms: dict[str, float] = {}
    corr: dict[str, Correction] = {}
    corr_record: dict[str, dict[str, Any]] = {}
    for axis, names in effects.items():
        selector = Selector([blocks(r, axis, estimator.tau_s) for r in runs], scaling)
        search = [n for n in EFFECTS if n in names and n in TAU_GRIDS]
        ev = selector.evaluate({n: 0.0 for n in EFFECTS if n in names}, search=search)
        base_rms[axis] = selector.evaluate({}).heldout_rms_dps
        rms[axis] = ev.heldout_rms_dps
        models[axis] = selector.model(ev)
        if corrections and axis in corrections:
            corr[axis], corr_record[axis] = correction_for(
                selector, ev, corrections[axis],
                n_knots=(correction_knots or {}).get(axis, N_KNOTS),
                source=f"unexplained structure of the diagnosis, axis {axis}: linear spline "
                       "fitted to the calibration's residuals (1-s blocks)")
    t = np.concatenate([r.temperature_c for r in runs])
    d = np.concatenate([r.delta_t_c for r in runs])
    record = {
        "method": "pooled, one offset per run, 1-s blocks",
        "runs": [{"name": r.name, "source": r.source, "sha256": r.sha256,
                  "rows": len(r.time_s)} for r in runs],
        "effects_fit": {a: {"effects": [n for n in EFFECTS if n in effects[a]],
                            "heldout_rms_dps": rms[a],
                            "baseline_heldout_rms_dps": base_rms[a],
                            "gain": base_rms[a] / rms[a],
                            **({"correction": corr_record[a]} if a in corr_record else {})}
                         for a in effects},
        "fit_time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "gyrotherm_version": __version__,
        **(provenance or {}),
    }
    cal = calibration_from_models(
        models, estimator=estimator,
        valid_range=ValidRange(float(t.min()), float(t.max()), float(d.min()), float(d.max())),
        t_on_max_s=max(float(r.time_s[-1]) for r in runs), provenance=record)
    from dataclasses import replace

    if corr:
        cal = replace(cal, effects={**cal.effects, **{
            a: replace(cal.effects_of(a), correction=c) for a, c in corr.items()}})
    residuals = {s.axis + ":" + s.run: s.compensated.to_dict()
                 for r in runs for s in score(cal, r)}
    cal = replace(cal, provenance={**cal.provenance, "residuals": residuals})
    return EffectsFit(cal, models, base_rms, rms)
