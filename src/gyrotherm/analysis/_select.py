"""Fitting, leave-one-run-out scoring and forward selection of effects.

Per run r, the design X_r (paper terms + effect columns) and the rate y_r are
centred on the run's own means: that is the least-squares fit with one
intercept per run (a switch-on offset, which no model predicts), by
Frisch–Waugh. Everything then follows from the per-run cross-products
M_r = [X̃_r ỹ_r]ᵀ[X̃_r ỹ_r]:

* fit on a set of runs S: c = (Σ_S X̃ᵀX̃)⁻¹ Σ_S X̃ᵀỹ (columns equilibrated, SVD solve);
* SSE_r(c) = ỹᵀỹ − 2cᵀX̃ᵀỹ + cᵀX̃ᵀX̃c;
* leave-one-run-out: c₋ᵣ from Σ M − M_r, scored on run r. The held-out score
  removes run r's own mean residual (its offset: one number, no shape).
  A time constant is re-searched on the grid in every fold;
  time constants of effects already in the model stay at their full-data values.

Held-out RMS = √(Σ_r SSE_r(c₋ᵣ) / Σ_r n_r) on the 1-s blocks.

Penalised criterion: BIC with an effective sample size,
n_eff = n / τ_int, where τ_int = 1 + 2 Σ ρ_k is the integrated autocorrelation
time (blocks) of the candidate model's residuals, summed until ρ_k first
drops below 0.05. With Gauss–Markov noise, white-noise BIC over ~10⁵
correlated blocks would accept any regressor; n_eff does not.

An effect enters (greedy forward selection, best held-out RMS first) only when
(1) held-out RMS improves by at least ``margin`` (relative), (2) the held-out
SSE improves on at least half of the runs, and (3) ΔBIC_eff < 0. After each
entry, the time constants are refined jointly; at the end, effects whose
removal no longer costs ``margin`` are dropped (backward pass).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from gyrotherm.analysis._effects import EFFECTS, TAU_GRIDS, ExtendedModel, design
from gyrotherm.analysis._prep import Prepared
from gyrotherm.compensation import Scaling

FloatArray = NDArray[np.float64]


def _design_run(p: Prepared, scaling: Scaling, effects: Mapping[str, float]) -> tuple[
    tuple[str, ...], FloatArray
]:
    return design(p.time_s, p.temperature_c, p.delta_t_c, p.direction, scaling, effects)


def cross_products(
    runs: Sequence[Prepared], scaling: Scaling, effects: Mapping[str, float]
) -> tuple[tuple[str, ...], FloatArray]:
    """Column names and the per-run centred cross-products, shape (R, k+1, k+1)."""
    out = []
    names: tuple[str, ...] = ()
    for p in runs:
        names, x = _design_run(p, scaling, effects)
        z = np.column_stack([x, p.rate_dps])
        z = z - z.mean(axis=0)
        out.append(z.T @ z)
    return names, np.array(out)


def solve(m: FloatArray) -> FloatArray:
    """Coefficients from a summed cross-product matrix (last row/column = y)."""
    a, b = m[:-1, :-1], m[:-1, -1]
    d = np.sqrt(np.maximum(np.diag(a), 1e-300))
    coef, *_ = np.linalg.lstsq(a / np.outer(d, d), b / d, rcond=1e-12)
    return np.asarray(coef / d, dtype=np.float64)


def sse(m: FloatArray, coef: FloatArray) -> float:
    a, b, yy = m[:-1, :-1], m[:-1, -1], m[-1, -1]
    return float(max(yy - 2.0 * coef @ b + coef @ a @ coef, 0.0))


def integrated_time(residuals: Sequence[FloatArray]) -> float:
    """Integrated autocorrelation time (samples) of residual series, pooled over runs."""
    num: FloatArray | None = None
    den = 0.0
    kmax = max(2, min(len(r) for r in residuals) // 4)
    for r in residuals:
        r = r - r.mean()
        n = len(r)
        f = np.fft.rfft(r, 2 * n)
        acov = np.fft.irfft(f * np.conj(f))[:kmax]
        num = acov if num is None else num + acov
        den += float(acov[0])
    assert num is not None
    if den <= 0:
        return 1.0
    rho = num / den
    below = np.flatnonzero(rho < 0.05)
    cut = int(below[0]) if len(below) else kmax
    return float(max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:cut]))))


@dataclass(frozen=True)
class Evaluation:
    """A model (paper + effects with their time constants) scored on the runs."""

    effects: Mapping[str, float]
    columns: tuple[str, ...]
    coefficients: FloatArray
    rss: float
    n: int
    heldout_sse: FloatArray
    heldout_n: FloatArray
    n_eff: float
    k: int

    @property
    def heldout_rms_dps(self) -> float:
        return math.sqrt(float(np.sum(self.heldout_sse)) / float(np.sum(self.heldout_n)))

    def bic(self, n_eff: float | None = None) -> float:
        ne = self.n_eff if n_eff is None else n_eff
        return ne * math.log(max(self.rss, 1e-300) / self.n) + self.k * math.log(ne)


class Selector:
    """Scores models on a fixed set of prepared runs (one axis, one scaling)."""

    def __init__(self, runs: Sequence[Prepared], scaling: Scaling) -> None:
        if len(runs) < 2:
            raise ValueError("leave-one-run-out needs at least 2 runs")
        self.runs = list(runs)
        self.scaling = scaling
        self.n_runs = np.array([len(p) for p in runs], dtype=np.float64)
        self._cache: dict[tuple[tuple[str, float], ...], tuple[tuple[str, ...], FloatArray]] = {}

    def _cp(self, effects: Mapping[str, float]) -> tuple[tuple[str, ...], FloatArray]:
        key = tuple(sorted((k, round(v, 6)) for k, v in effects.items()))
        if key not in self._cache:
            if len(self._cache) > 4000:
                self._cache.clear()
            self._cache[key] = cross_products(self.runs, self.scaling, effects)
        return self._cache[key]

    def residuals(self, effects: Mapping[str, float], coef: FloatArray) -> list[FloatArray]:
        out = []
        for p in self.runs:
            _, x = _design_run(p, self.scaling, effects)
            r = p.rate_dps - x @ coef
            out.append(r - r.mean())
        return out

    def full_rss(self, effects: Mapping[str, float]) -> float:
        _, m = self._cp(effects)
        total = m.sum(axis=0)
        return sse(total, solve(total))

    def evaluate(self, effects: Mapping[str, float], *, search: str | None = None) -> Evaluation:
        """Fit on all runs and leave-one-run-out; ``search`` names the effect whose
        time constant is chosen on its grid per fold (and on all runs)."""
        grid = TAU_GRIDS.get(search, ()) if search else ()
        if grid and search is not None:
            options = [{**effects, search: v} for v in grid]
        else:
            options = [dict(effects)]
        cps = [self._cp(o) for o in options]
        names = cps[0][0]
        mats = np.array([m for _, m in cps])  # (V, R, k+1, k+1)
        totals = mats.sum(axis=1)
        full_rss = [sse(t, solve(t)) for t in totals]
        best = int(np.argmin(full_rss))
        chosen = options[best]
        if grid and search is not None:
            chosen = {**effects, search: self._refine(effects, search, best, grid)}
            if chosen[search] < 1e-3:
                chosen = options[best]
        _, m_best = self._cp(chosen)
        total = m_best.sum(axis=0)
        coef = solve(total)
        rss = sse(total, coef)
        held = np.empty(len(self.runs))
        for r in range(len(self.runs)):
            train = totals - mats[:, r]
            coefs = [solve(t) for t in train]
            v = int(np.argmin([sse(t, c) for t, c in zip(train, coefs, strict=True)]))
            held[r] = sse(mats[v, r], coefs[v])
        resid = self.residuals(chosen, coef)
        n = int(self.n_runs.sum())
        n_eff = max(n / integrated_time(resid), 2.0 * len(names) + 2.0)
        k = len(names) + sum(1 for e in chosen if e in TAU_GRIDS)
        return Evaluation(chosen, names, coef, rss, n, held, self.n_runs.copy(), n_eff, k)

    def _refine(
        self, effects: Mapping[str, float], name: str, best: int, grid: Sequence[float]
    ) -> float:
        if grid[best] <= 0.0:
            return grid[best]
        lo = math.log(max(grid[max(best - 1, 0)], grid[best] / 2))
        hi = math.log(grid[min(best + 1, len(grid) - 1)])
        if hi - lo < 1e-9:
            return grid[best]
        res = minimize_scalar(lambda u: self.full_rss({**effects, name: math.exp(u)}),
                              bounds=(lo, hi), method="bounded",
                              options={"xatol": 0.01})
        return float(math.exp(float(res.x)))

    def model(self, ev: Evaluation) -> ExtendedModel:
        offsets = {}
        for p, r in zip(self.runs, self.residuals_raw(ev), strict=True):
            offsets[p.name] = float(r.mean())
        return ExtendedModel(
            scaling=self.scaling,
            effects=dict(ev.effects),
            columns=ev.columns,
            coefficients=tuple(float(c) for c in ev.coefficients),
            intercept_dps=float(np.mean(list(offsets.values()))),
            offsets_dps=offsets,
        )

    def residuals_raw(self, ev: Evaluation) -> list[FloatArray]:
        """Residuals before removing each run's offset."""
        out = []
        for p in self.runs:
            _, x = _design_run(p, self.scaling, ev.effects)
            out.append(p.rate_dps - x @ ev.coefficients)
        return out


@dataclass(frozen=True)
class Step:
    """One accepted effect with the evidence for it."""

    effect: str
    before: Evaluation
    after: Evaluation
    runs_improved: int
    delta_bic: float


@dataclass(frozen=True)
class Selection:
    baseline: Evaluation
    final: Evaluation
    steps: tuple[Step, ...]
    alone: Mapping[str, Evaluation]
    tried: Mapping[str, tuple[float, int, float]]
    """Per effect tried on the baseline: (held-out ratio, runs improved, ΔBIC)."""


def _compare(before: Evaluation, after: Evaluation) -> tuple[float, int, float]:
    ratio = before.heldout_rms_dps / after.heldout_rms_dps
    improved = int(np.sum(after.heldout_sse < before.heldout_sse))
    n_eff = min(before.n_eff, after.n_eff)
    delta_bic = after.bic(n_eff) - before.bic(n_eff)
    return ratio, improved, delta_bic


def select(
    selector: Selector,
    *,
    margin: float = 0.10,
    candidates: Sequence[str] = EFFECTS,
    pairs: bool = True,
    progress: Callable[[str], None] | None = None,
) -> Selection:
    """Greedy forward selection with a backward pass (see the module docstring).

    With ``pairs``, every step also tries each pair of remaining effects and
    takes the best pair when it beats the best single effect by the same
    criteria: two effects can cancel each other (a lag and a hysteresis of
    opposite signs) so that neither helps alone.
    """
    say = progress or (lambda _msg: None)
    need = math.ceil(len(selector.runs) / 2)

    def passes(before: Evaluation, after: Evaluation) -> bool:
        ratio, improved, dbic = _compare(before, after)
        return ratio >= 1.0 + margin and improved >= need and dbic < 0.0

    baseline = selector.evaluate({})
    current = baseline
    steps: list[Step] = []
    alone: dict[str, Evaluation] = {}
    tried: dict[str, tuple[float, int, float]] = {}
    while True:
        singles: dict[str, Evaluation] = {}
        for name in candidates:
            if name in current.effects:
                continue
            trial = selector.evaluate({**current.effects, name: 0.0}, search=name)
            singles[name] = trial
            if not current.effects:
                alone[name] = trial
                tried[name] = _compare(baseline, trial)
                say(f"{name}: held-out gain {tried[name][0]:.3f}, runs improved "
                    f"{tried[name][1]}/{len(selector.runs)}, ΔBIC_eff {tried[name][2]:.1f}")
        passing = [(ev.heldout_rms_dps, n) for n, ev in singles.items() if passes(current, ev)]
        best_single = singles[min(passing)[1]] if passing else None
        best_pair: Evaluation | None = None
        pair_names: tuple[str, str] = ("", "")
        if pairs:
            names = sorted(singles, key=EFFECTS.index)
            for i, a in enumerate(names):
                for b in names[i + 1:]:
                    trial = _pair(selector, current, singles, a, b)
                    if passes(current, trial) and (
                            best_pair is None or trial.heldout_rms_dps < best_pair.heldout_rms_dps):
                        best_pair, pair_names = trial, (a, b)
        if best_pair is not None and (best_single is None or passes(best_single, best_pair)):
            ratio, improved, dbic = _compare(current, best_pair)
            refined = _refine_all(selector, best_pair)
            for name in pair_names:
                steps.append(Step(name, current, refined, improved, dbic))
            say(f"accepted {' + '.join(pair_names)} together (held-out gain {ratio:.3f})")
            current = refined
            continue
        if best_single is None:
            break
        name = min(passing)[1]
        ratio, improved, dbic = _compare(current, best_single)
        refined = _refine_all(selector, best_single)
        steps.append(Step(name, current, refined, improved, dbic))
        say(f"accepted {name} (held-out gain {ratio:.3f})")
        current = refined
    # backward pass: drop effects that no longer earn their place
    changed = True
    while changed and current.effects:
        changed = False
        for name in list(current.effects):
            rest = {k: v for k, v in current.effects.items() if k != name}
            without = _refine_all(selector, selector.evaluate(rest))
            if not passes(without, current):
                say(f"dropped {name} (redundant given the others)")
                current = without
                steps = [s for s in steps if s.effect != name]
                changed = True
                break
    for name in current.effects:
        if name not in alone:
            alone[name] = selector.evaluate({name: 0.0}, search=name)
    return Selection(baseline, current, tuple(steps), alone, tried)


def _pair(
    selector: Selector, current: Evaluation, singles: Mapping[str, Evaluation], a: str, b: str
) -> Evaluation:
    """``current`` + effects a and b; time constants start from their single-effect fits."""
    effects = {**current.effects, a: singles[a].effects[a], b: singles[b].effects[b]}
    nonlinear = [e for e in (a, b) if e in TAU_GRIDS]
    if not nonlinear:
        return selector.evaluate(effects)
    ev = selector.evaluate(effects, search=nonlinear[0])
    for name in nonlinear[1:]:
        ev = selector.evaluate(dict(ev.effects), search=name)
    return ev


def _refine_all(selector: Selector, ev: Evaluation, rounds: int = 2) -> Evaluation:
    """Coordinate descent over the time constants of the model's effects."""
    nonlinear = [e for e in ev.effects if e in TAU_GRIDS]
    if not nonlinear or len(ev.effects) < 2:
        return ev
    current = ev
    for _ in range(rounds):
        for name in nonlinear:
            current = selector.evaluate(dict(current.effects), search=name)
    return current
