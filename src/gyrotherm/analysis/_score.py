"""Fitting and leave-one-run-out scoring of a model (paper terms + effects).

Per run r, the design X_r (paper terms + effect columns) and the rate y_r are
centred on the run's own means: that is the least-squares fit with one
intercept per run (a switch-on offset, which no model predicts), by
Frisch–Waugh. Everything then follows from the per-run cross-products
M_r = [X̃_r ỹ_r]ᵀ[X̃_r ỹ_r]:

* fit on a set of runs S: c = (Σ_S X̃ᵀX̃)⁻¹ Σ_S X̃ᵀỹ (columns equilibrated, SVD solve);
* SSE_r(c) = ỹᵀỹ − 2cᵀX̃ᵀỹ + cᵀX̃ᵀX̃c;
* leave-one-run-out: c₋ᵣ from Σ M − M_r, scored on run r. The held-out score
  removes run r's own mean residual (its offset: one number, no shape).
  The searched nonlinear parameters (time constants, the hysteresis
  transition) are re-chosen in every fold, by training RSS, among the grid
  points and the all-runs optimum; the others stay at their all-runs values.

Held-out RMS = √(Σ_r SSE_r(c₋ᵣ) / Σ_r n_r) on the 1-s blocks.

Nonlinear parameters: one is searched on its log grid, several jointly on the
product of their coarse grids (every other point: 13 × 7 for lag ×
hysteresis); the best grid point (all-runs RSS: profile likelihood) is then
refined continuously in log space (bounded scalar search, or Nelder–Mead).
A warm-up's τ is searched up to a third of the shortest run: a transient that
does not decay within the runs cannot be told from a drift.

Penalised criterion: BIC with an effective sample size,
n_eff = n / τ_int, where τ_int = 1 + 2 Σ ρ_k is the integrated autocorrelation
time (blocks) of the candidate model's residuals, summed until ρ_k first
drops below 0.05. With Gauss–Markov noise, white-noise BIC over ~10⁵
correlated blocks would accept any regressor; n_eff does not. k counts the
columns and the nonlinear parameters.

Columns are cached per run (:data:`~gyrotherm.analysis._effects.ColumnCache`)
and cross-products per effect set, so a search revisits nothing.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize, minimize_scalar

from gyrotherm.analysis._effects import TAU_GRIDS, ColumnCache, ExtendedModel, design
from gyrotherm.analysis._prep import Prepared
from gyrotherm.compensation import Scaling

FloatArray = NDArray[np.float64]
_MAX_COLUMNS = 1500
"""Columns kept per run (each one run long) before the column cache is emptied."""
WARMUP_SPAN = 3.0
"""A warm-up's τ is searched up to (time since power-on at the end of the shortest run)
/ WARMUP_SPAN: a transient that has not decayed within the runs is a drift."""


def _design_run(
    p: Prepared, scaling: Scaling, effects: Mapping[str, float],
    cache: ColumnCache | None = None, *, coupled: bool = True,
) -> tuple[tuple[str, ...], FloatArray]:
    return design(p.time_s, p.temperature_c, p.delta_t_c, scaling, effects, cache=cache,
                  hysteresis_follows_lag=coupled)


def cross_products(
    runs: Sequence[Prepared], scaling: Scaling, effects: Mapping[str, float],
    caches: Sequence[ColumnCache] | None = None, *, coupled: bool = True,
) -> tuple[tuple[str, ...], FloatArray]:
    """Column names and the per-run centred cross-products, shape (R, k+1, k+1)."""
    out = []
    names: tuple[str, ...] = ()
    for i, p in enumerate(runs):
        y = p.rate_dps - p.rate_dps.mean()
        names, z = design(p.time_s, p.temperature_c, p.delta_t_c, scaling, effects,
                          cache=caches[i] if caches else None, centred=True, append=y,
                          hysteresis_follows_lag=coupled)
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

    def __init__(
        self, runs: Sequence[Prepared], scaling: Scaling, *, hysteresis_follows_lag: bool = True
    ) -> None:
        if len(runs) < 2:
            raise ValueError("leave-one-run-out needs at least 2 runs")
        self.runs = list(runs)
        self.scaling = scaling
        self.coupled = hysteresis_follows_lag
        self.grids = dict(TAU_GRIDS)
        # a warm-up must be seen to decay: τ at most a third of the shortest run
        shortest = min(float(p.time_s[-1]) for p in runs if len(p)) if runs else 0.0
        warm = [g for g in TAU_GRIDS["warmup"] if g <= shortest / WARMUP_SPAN]
        self.grids["warmup"] = tuple(warm) if len(warm) >= 4 else TAU_GRIDS["warmup"][:4]
        self.n_runs = np.array([len(p) for p in runs], dtype=np.float64)
        self._cache: dict[tuple[tuple[str, float], ...], tuple[tuple[str, ...], FloatArray]] = {}
        self._columns: list[ColumnCache] = [{} for _ in runs]

    def _cp(self, effects: Mapping[str, float]) -> tuple[tuple[str, ...], FloatArray]:
        key = tuple(sorted((k, round(v, 6)) for k, v in effects.items()))
        if key not in self._cache:
            if len(self._cache) > 4000:
                self._cache.clear()
            if len(self._columns[0]) > _MAX_COLUMNS:
                for c in self._columns:
                    c.clear()
            self._cache[key] = cross_products(self.runs, self.scaling, effects, self._columns,
                                              coupled=self.coupled)
        return self._cache[key]

    def residuals(self, effects: Mapping[str, float], coef: FloatArray) -> list[FloatArray]:
        out = []
        for p, cache in zip(self.runs, self._columns, strict=True):
            _, x = _design_run(p, self.scaling, effects, cache, coupled=self.coupled)
            r = p.rate_dps - x @ coef
            out.append(r - r.mean())
        return out

    def full_rss(self, effects: Mapping[str, float]) -> float:
        _, m = self._cp(effects)
        total = m.sum(axis=0)
        return sse(total, solve(total))

    def evaluate(
        self, effects: Mapping[str, float], *, search: str | Sequence[str] | None = None
    ) -> Evaluation:
        """Fit on all runs and leave-one-run-out.

        ``search`` names the effect(s) whose nonlinear parameter is chosen: one on
        its grid, several jointly on the product of their coarse grids (every
        other point); the best grid point on all runs is then refined
        continuously (:meth:`_refine`), and every fold picks its own option
        among the grid points and the refined one by its training RSS.
        """
        names = (search,) if isinstance(search, str) else tuple(search or ())
        names = tuple(n for n in names if n in TAU_GRIDS)
        grids = [self.grids[n] if len(names) == 1 else self.grids[n][::2] for n in names]
        options = [{**effects, **dict(zip(names, combo, strict=True))}
                   for combo in itertools.product(*grids)] if names else [dict(effects)]
        full_rss = [self.full_rss(o) for o in options]
        chosen = options[int(np.argmin(full_rss))]
        if names:
            chosen = self._refine(chosen, names, grids)
            options.append(chosen)
        cps = [self._cp(o) for o in options]
        names_cols = cps[0][0]
        mats = np.array([m for _, m in cps])  # (V, R, k+1, k+1)
        totals = mats.sum(axis=1)
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
        n_eff = max(n / integrated_time(resid), 2.0 * len(names_cols) + 2.0)
        k = len(names_cols) + sum(1 for e in chosen if e in TAU_GRIDS)
        return Evaluation(chosen, names_cols, coef, rss, n, held, self.n_runs.copy(), n_eff, k)

    def _refine(
        self, start: Mapping[str, float], names: Sequence[str], grids: Sequence[Sequence[float]]
    ) -> dict[str, float]:
        """Continuous minimum of the all-runs RSS around the best grid point ``start``.

        Works on log parameters, within one grid step of ``start`` (one name:
        bounded scalar search; several: Nelder–Mead with one-step initial
        simplex, clipped to two grid steps around ``start`` and below the grid's
        top). A parameter at 0 stays 0.
        """
        free = [n for n in names if start[n] > 0.0]
        if not free:
            return dict(start)
        lo, hi, step = {}, {}, {}
        for n, grid in zip(names, grids, strict=True):
            positive = [g for g in grid if g > 0.0]
            i = positive.index(start[n]) if start[n] in positive else 0
            step[n] = math.log(positive[1] / positive[0]) if len(positive) > 1 else 0.1
            lo[n] = math.log(positive[max(i - 1, 0)]) if i > 0 else math.log(positive[0] / 2)
            hi[n] = math.log(positive[min(i + 1, len(positive) - 1)])
        if len(free) == 1:
            (n,) = free
            if hi[n] - lo[n] < 1e-9:
                return dict(start)
            res = minimize_scalar(lambda u: self.full_rss({**start, n: math.exp(u)}),
                                  bounds=(lo[n], hi[n]), method="bounded",
                                  options={"xatol": 0.02})
            value = float(math.exp(float(res.x)))
            best = {**start, n: value}
            return best if self.full_rss(best) <= self.full_rss(start) else dict(start)

        top = {n: math.log(max(self.grids[n])) for n in free}

        def params(u: FloatArray) -> dict[str, float]:
            out = dict(start)
            for n, x in zip(free, u, strict=True):
                out[n] = math.exp(min(max(float(x), lo[n] - step[n]), hi[n] + step[n], top[n]))
            return out

        x0 = np.array([math.log(start[n]) for n in free])
        simplex = np.vstack([x0] + [x0 + step[n] * np.eye(len(free))[j]
                                    for j, n in enumerate(free)])
        res = minimize(lambda u: self.full_rss(params(u)), x0, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": 0.02,
                                "fatol": 1e-9 * self.full_rss(start), "maxfev": 40})
        best = params(np.asarray(res.x, dtype=np.float64))
        return best if self.full_rss(best) <= self.full_rss(start) else dict(start)

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
            _, x = _design_run(p, self.scaling, ev.effects, coupled=self.coupled)
            out.append(p.rate_dps - x @ ev.coefficients)
        return out
