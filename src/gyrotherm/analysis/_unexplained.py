"""Residual structure no catalogued effect explains: a nonparametric correction.

After selection, the chosen (catalogued) model may still leave structure in
one variable v ∈ :data:`VARIABLES` (the temperature estimate T, °C; the
gradient estimate ΔT, °C; time since power-on, s). The correction is a linear
spline in v, c(v) = Σ_k β_k·φ_k(v), with hat functions φ_k on
K knots spaced evenly over the runs' range of v (constant beyond it; K of
:data:`KNOT_COUNTS`, of those with ΔBIC_eff < 0 the one with the lowest held-out RMS,
:func:`spline_knots`:
at a coarse readout the blocks' residuals are correlated over minutes, n_eff is small,
and 11 columns can fail ΔBIC_eff where 4–7 pass with the same held-out gain; the
first hat is left out: the hats sum to 1, which the per-run offsets already hold).
It is fitted *jointly* with the model's columns, with
one offset per run, and scored exactly like the effects (:mod:`._score`):
leave-one-run-out held-out RMS, runs improved, ΔBIC_eff with k counting the
K − 1 spline columns. It is reported only when it passes the same entry
criteria as an effect against the chosen model (held-out ratio ≥ 1 + margin,
better on at least half of the left-out runs, ΔBIC_eff < 0).

When it passes, every catalogued effect of the model is checked again with
the correction present: one that no longer earns its place (the same
criteria) was only standing in for the unexplained structure (a cubic
bending towards a step) and is dropped.

The spline reported is fitted to the final model's residuals (two-stage, so
that the paper's T and T² terms, collinear with the spline, do not share its
shape). ``where`` = [low, high]: the whole span of v over which it changes
significantly (:mod:`._where`: its monotone runs, reversals within the noise
smoothed over, every run whose change is ≥ 3 standard errors, first to last,
padded by one knot interval); ``steepest``: the knot intervals, contiguous with the
steepest one, whose slope |Δc/Δv| is at least half the steepest (how sharp the
structure is, for :mod:`._resolution`). ``gain`` = held-out RMS of the model
without the correction / with it; the model is the final one (the catalogued effects that
remain and every other structure found).

``not_told_from``: each variable not found is tried in the structure's place on that same
model; one whose spline passes the entry criteria and is not beaten by ×(1 + margin) held
out is listed with its gain: which variable the structure is in is not resolvable at this
readout (runs that repeat one temperature profile move T, ΔT and time together). An empty
listing says no other variable's spline (at the knot counts tried) does as well, not that
the runs tell the variables apart everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._catalogued_rivals import listing
from gyrotherm.analysis._effects import TAU_GRIDS, design
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._score import Evaluation, Selector, integrated_time, sse
from gyrotherm.analysis._where import support_span, values_with_covariance

FloatArray = NDArray[np.float64]

VARIABLES = ("temperature_c", "delta_t_c", "time_since_power_on_s")
N_KNOTS = 12
KNOT_COUNTS = (12, 8, 6, 5)
"""The knot counts a spline in one variable may have; the search takes, of those with
ΔBIC_eff < 0, the one with the lowest held-out RMS (:func:`spline_knots`)."""
SMOOTHING = 0.1
"""λ of the first-difference penalty on the spline, relative to its columns' scale."""


@dataclass(frozen=True)
class Unexplained:
    """A significant residual structure in ``variable`` no catalogued effect explains."""

    variable: str
    where: tuple[float, float]
    knots: tuple[float, ...]
    correction_dps: tuple[float, ...]
    """Two-stage correction (°/s) at the knots, zero mean over the runs' blocks."""
    heldout_rms_dps: float
    gain: float
    evidence: str
    steepest: tuple[float, float] = (math.nan, math.nan)
    """The steepest part of ``where`` (knot intervals at least half as steep)."""
    not_told_from: Mapping[str, float] = field(default_factory=dict)
    """Other variables whose spline in this one's place also passes the entry criteria and
    is not beaten by ×(1 + margin) held out (variable → its held-out gain): which of them
    the structure is in is not resolvable at this readout (:func:`search_unexplained`;
    extended by :mod:`._rival_power`: a variable the runs prefer to it only as much as this
    readout would if the structure were in that variable)."""
    effects_not_told_from: Mapping[str, float] = field(default_factory=dict)
    """Catalogued effects (not in the model, not left out by a verdict) that do as well in
    its place, or that the runs do not tell from it at this readout (:mod:`._rival_power`;
    effect → its held-out gain in the structure's place)."""

    @property
    def rivals(self) -> str:
        """``not_told_from``'s variables, "delta_t_c or temperature_c" ("" when none)."""
        return " or ".join(sorted(self.not_told_from))

    @property
    def effect_rivals(self) -> str:
        """``effects_not_told_from``'s effects, "a cubic or a hysteresis" ("" when none)."""
        return " or ".join(f"a {e}" for e in sorted(self.effects_not_told_from))

    @property
    def alike(self) -> str:
        """Every rival, "a structure in delta_t_c or a hysteresis" ("" when none)."""
        return " or ".join(t for t in (self.rivals and f"a structure in {self.rivals}",
                                       self.effect_rivals) if t)

    def to_dict(self) -> dict[str, Any]:
        return {"effect": "unexplained",
                "params": {"variable": self.variable, "where": list(self.where),
                           "steepest": list(self.steepest),
                           "not_told_from": dict(self.not_told_from),
                           "not_told_from_effects": dict(self.effects_not_told_from)},
                "gain": self.gain, "heldout_rms_dps": self.heldout_rms_dps,
                "evidence": self.evidence,
                "correction": {"kind": "linear spline", "knots": list(self.knots),
                               "values_dps": list(self.correction_dps),
                               "deployable": True}}


def variable(p: Prepared, name: str) -> FloatArray:
    """The per-block values of variable ``name`` in run ``p``."""
    if name == "temperature_c":
        return p.temperature_c
    if name == "delta_t_c":
        return p.delta_t_c
    if name == "time_since_power_on_s":
        return p.time_s
    raise ValueError(f"unknown variable {name!r}; known: {', '.join(VARIABLES)}")


def knots_for(runs: Sequence[Prepared], name: str, n_knots: int = N_KNOTS) -> FloatArray:
    """``n_knots`` evenly spaced knots over the runs' 0.5–99.5 % range of ``name``."""
    v = np.concatenate([variable(p, name) for p in runs])
    lo, hi = np.percentile(v, [0.5, 99.5])
    if hi - lo <= 1e-9:
        hi = lo + 1.0
    return np.linspace(float(lo), float(hi), n_knots)


def hats(values: FloatArray, knots: FloatArray) -> FloatArray:
    """Hat functions φ_k(v) (n × K): linear interpolation weights, constant outside."""
    v = np.clip(values, knots[0], knots[-1])
    out = np.zeros((len(v), len(knots)))
    i = np.clip(np.searchsorted(knots, v, side="right") - 1, 0, len(knots) - 2)
    w = (v - knots[i]) / (knots[i + 1] - knots[i])
    rows = np.arange(len(v))
    out[rows, i] = 1.0 - w
    out[rows, i + 1] += w
    return out


def _centred(a: FloatArray) -> FloatArray:
    return np.asarray(a - a.mean(axis=0, keepdims=True), dtype=np.float64)


def evaluate_with(
    selector: Selector, effects: Mapping[str, float],
    splines: Sequence[tuple[str, FloatArray]],
    *, extra: Mapping[str, Callable[[Prepared], FloatArray]] | None = None,
) -> Evaluation:
    """The model ``effects`` (nonlinear parameters fixed) plus the linear splines
    (variable, knots), fitted jointly, one offset per run, scored leave-one-run-out.
    ``extra``: further columns (name → the column of a run), unpenalised, fitted with
    the model's."""
    mats, xs, ys = [], [], []
    columns: tuple[str, ...] = ()
    more = dict(extra or {})
    for p in selector.runs:
        columns, x = design(p.time_s, p.temperature_c, p.delta_t_c, selector.scaling,
                            effects, hysteresis_follows_lag=selector.coupled)
        columns = (*columns, *more)
        blocks = ([x, *(np.asarray(f(p), dtype=np.float64)[:, None] for f in more.values())]
                  + [hats(variable(p, v), k)[:, 1:] for v, k in splines])
        z = _centred(np.hstack(blocks))
        y = p.rate_dps - p.rate_dps.mean()
        xs.append(z)
        ys.append(y)
        zy = np.column_stack([z, y])
        mats.append(zy.T @ zy)
    m = np.array(mats)
    total = m.sum(axis=0)
    pen = _penalty(total, len(columns), [len(k) - 1 for _, k in splines])
    coef = _psolve(total, pen)
    held = np.array([sse(m[r], _psolve(total - m[r], pen)) for r in range(len(m))])
    resid = [y - z @ coef for z, y in zip(xs, ys, strict=True)]
    n = int(selector.n_runs.sum())
    names = (*columns, *(f"{v}[{j}]" for v, k in splines for j in range(1, len(k))))
    n_eff = max(n / integrated_time(resid), 2.0 * len(names) + 2.0)
    k = len(names) + sum(1 for e in effects if e in TAU_GRIDS)
    return Evaluation(dict(effects), names, coef, sse(total, coef), n, held,
                      selector.n_runs.copy(), n_eff, k)


def _penalty(total: FloatArray, n_model: int, sizes: Sequence[int]) -> FloatArray:
    """λ·DᵀD on each spline's coefficients, D the first differences (β₀ = 0 for the
    hat left out), λ = :data:`SMOOTHING` × the median diagonal of its columns'
    cross-product: a knot few blocks reach (a range one run alone covers) follows
    its neighbours instead of being free, so a left-out run is not extrapolated
    wildly."""
    p = total.shape[0] - 1
    pen = np.zeros((p, p))
    start = n_model
    for size in sizes:
        d = np.eye(size) - np.eye(size, k=-1)
        diag = np.diag(total)[start: start + size]
        lam = SMOOTHING * float(np.median(diag))
        pen[start: start + size, start: start + size] = lam * d.T @ d
        start += size
    return pen


def _psolve(m: FloatArray, pen: FloatArray) -> FloatArray:
    """Penalised least squares from a cross-product matrix (last row/column = y)."""
    a = m[:-1, :-1] + pen
    b = m[:-1, -1]
    d = np.sqrt(np.maximum(np.diag(a), 1e-300))
    coef, *_ = np.linalg.lstsq(a / np.outer(d, d), b / d, rcond=1e-12)
    return np.asarray(coef / d, dtype=np.float64)


def two_stage(
    runs: Sequence[Prepared], residuals: Sequence[FloatArray], name: str, knots: FloatArray
) -> FloatArray:
    """Spline values at the knots fitted to ``residuals`` (one offset per run), zero
    mean over the blocks."""
    b = np.vstack([_centred(hats(variable(p, name), knots)) for p in runs])
    e = np.concatenate([r - r.mean() for r in residuals])
    beta, *_ = np.linalg.lstsq(b, e, rcond=1e-10)
    fitted = np.vstack([hats(variable(p, name), knots) for p in runs]) @ beta
    return np.asarray(beta - fitted.mean(), dtype=np.float64)


def steepest_span(knots: FloatArray, values: FloatArray) -> tuple[float, float]:
    """[low, high]: the knot intervals contiguous with the steepest one whose slope
    is at least half of its."""
    slope = np.abs(np.diff(values) / np.diff(knots))
    i = int(np.argmax(slope))
    lo = hi = i
    while lo > 0 and slope[lo - 1] >= 0.5 * slope[i]:
        lo -= 1
    while hi < len(slope) - 1 and slope[hi + 1] >= 0.5 * slope[i]:
        hi += 1
    return float(knots[lo]), float(knots[hi + 1])


def spline_knots(
    selector: Selector, effects: Mapping[str, float],
    chosen: Sequence[tuple[str, FloatArray]], name: str, current: Evaluation | None = None,
) -> FloatArray:
    """The knots of a spline in ``name`` on top of ``effects`` and the splines ``chosen``:
    of the counts in :data:`KNOT_COUNTS` whose ΔBIC_eff against that model is negative (the
    in-sample support the entry criteria require), the one with the lowest held-out RMS;
    when none is, the one with the lowest ΔBIC_eff (which then fails the entry criteria).
    ``current``: that model's evaluation, if already made.

    Round 12 of issue 19: the count used to be the lowest ΔBIC_eff alone. With n_eff ≈ 100
    blocks each column costs ln(n_eff) ≈ 4.6 in BIC, so a structure that needs the finer
    spline (a periodic bias of 15 °C period over 36 °C: held out ×1.20 with 12 knots, ×1.09
    with 8) was tried at the coarser count and failed the ×(1 + margin) held out that the
    finer one passed. Every null the structures must beat (:mod:`._null_replay`,
    :mod:`._floor`) chooses the count by this same rule, so the choice among counts is in
    the null too."""
    from gyrotherm.analysis._select import _compare

    before = current if current is not None else evaluate_with(selector, effects, chosen)
    trials: list[tuple[float, float, FloatArray]] = []
    for n in KNOT_COUNTS:
        k = knots_for(selector.runs, name, n)
        after = evaluate_with(selector, effects, [*chosen, (name, k)])
        _, _, dbic = _compare(before, after)
        trials.append((dbic, after.heldout_rms_dps, k))
    supported = [t for t in trials if t[0] < 0.0]
    if supported:
        return min(supported, key=lambda t: t[1])[2]
    return min(trials, key=lambda t: t[0])[2]


def heldout_rms(ev: Evaluation) -> float:
    return math.sqrt(float(np.sum(ev.heldout_sse)) / float(np.sum(ev.heldout_n)))


@dataclass(frozen=True)
class Search:
    """The catalogued model after the search (effects the correction made redundant
    dropped) and the unexplained structures found, with what was dropped."""

    catalogued: Evaluation
    unexplained: tuple[Unexplained, ...]
    dropped: tuple[str, ...]


def search_unexplained(
    selector: Selector, final: Evaluation, *, margin: float = 0.10,
    variables: Sequence[str] = VARIABLES,
) -> Search:
    """Greedy: the variable whose spline most improves the held-out RMS of the model
    so far, while one passes the entry criteria (module docstring); then drop the
    catalogued effects the splines make redundant."""
    from gyrotherm.analysis._select import _compare, _refine_all, enters

    def passes(before: Evaluation, after: Evaluation) -> bool:
        return enters(before, after, margin=margin, n_runs=len(selector.runs))

    effects = dict(final.effects)
    current = evaluate_with(selector, effects, [])
    chosen: list[tuple[str, FloatArray]] = []
    gains: dict[str, tuple[Evaluation, Evaluation]] = {}
    dropped: list[str] = []
    while len(chosen) < len(variables):
        # each spline on the model, and in place of each catalogued effect (a cubic
        # bent towards a step must not keep the step's spline below the margin)
        trials: dict[tuple[str, str], Evaluation] = {}
        knots = {v: spline_knots(selector, effects, chosen, v, current)
                 for v in variables if v not in dict(chosen)}
        for v in knots:
            for name in ("", *effects):
                rest = {k: x for k, x in effects.items() if k != name}
                trials[(v, name)] = evaluate_with(selector, rest, [*chosen, (v, knots[v])])
        ok = {key: ev for key, ev in trials.items() if passes(current, ev)}
        if not ok:
            break
        (best, gone) = min(ok, key=lambda key: (ok[key].heldout_rms_dps, key[1] != ""))
        if gone:
            effects.pop(gone)
            dropped.append(gone)
            current = evaluate_with(selector, effects, chosen)
        gains[best] = (current, ok[(best, gone)])
        chosen.append((best, knots[best]))
        current = ok[(best, gone)]
    if not chosen:
        return Search(final, (), ())
    for name in list(effects):
        rest = {k: v for k, v in effects.items() if k != name}
        if not passes(evaluate_with(selector, rest, chosen), current):
            dropped.append(name)
            effects = rest
            current = evaluate_with(selector, effects, chosen)
    catalogued = final
    if dropped:
        catalogued = _refine_all(selector, selector.evaluate(effects))
    resid = selector.residuals(catalogued.effects, catalogued.coefficients)
    found = []
    for v, k in chosen:
        before, after = gains[v]
        others = [(w, kk) for w, kk in chosen if w != v]
        if dropped or others:  # the gain over the final model: the catalogued effects that
            # remain and every other structure found (the basis its rivals are tried on)
            before = evaluate_with(selector, catalogued.effects, others)
            after = evaluate_with(selector, catalogued.effects, [*others, (v, k)])
        ratio, improved, dbic = _compare(before, after)
        rival = _rivals(selector, catalogued.effects, others, before, after,
                        [w for w in variables if w not in dict(chosen)], passes, margin)
        values, cov = values_with_covariance(
            [hats(variable(p, v), k) for p in selector.runs], resid, k)
        found.append(Unexplained(
            variable=v, where=support_span(k, values, cov), steepest=steepest_span(k, values),
            knots=tuple(float(x) for x in k), correction_dps=tuple(float(x) for x in values),
            heldout_rms_dps=after.heldout_rms_dps, gain=ratio, not_told_from=rival,
            evidence=(f"linear spline in {v} ({len(k)} knots) on top of "
                      f"{'+'.join(('paper', *catalogued.effects))}: held-out RMS "
                      f"{before.heldout_rms_dps:.5f} → {after.heldout_rms_dps:.5f} °/s, better "
                      f"on {improved}/{len(selector.runs)} left-out runs; ΔBIC_eff = "
                      f"{dbic:.1f}" + (f"; made {', '.join(dropped)} redundant" if dropped
                                       else "") + _rival_text(rival))))
    return Search(catalogued, tuple(found), tuple(dropped))


def _rivals(
    selector: Selector, effects: Mapping[str, float], others: Sequence[tuple[str, FloatArray]],
    before: Evaluation, after: Evaluation, candidates: Sequence[str],
    passes: Callable[[Evaluation, Evaluation], bool], margin: float,
) -> dict[str, float]:
    """The variables of ``candidates`` whose spline, in place of the one that took
    ``before`` to ``after`` (on the same catalogued model and other splines), also passes
    the entry criteria and is not beaten by it by ×(1 + ``margin``) held out: variable →
    its held-out gain over ``before``."""
    out: dict[str, float] = {}
    for w in candidates:
        k = spline_knots(selector, effects, others, w, before)
        ev = evaluate_with(selector, effects, [*others, (w, k)])
        if passes(before, ev) and ev.heldout_rms_dps < after.heldout_rms_dps * (1.0 + margin):
            out[w] = before.heldout_rms_dps / ev.heldout_rms_dps
    return out


def _rival_text(rival: Mapping[str, float]) -> str:
    return listing(rival, each="held out in its place", what="a structure in ",
                   said="which variable it is in is not resolvable at this readout (the runs "
                        "move them together)")
