"""Learning in the field: the paper model from ordinary power-ons, no chamber.

Every power-on of a vehicle at rest is a small chamber run: the die warms from the
ambient temperature A towards A + self-heating, so T rises while ΔT decays. Within one
warm-up T and ΔT move together (T ≈ A + S − ΔT at constant ambient), which is why the
autopilots' one-warm-up learners (ArduPilot ``INS_TCALn_ENABLE = 2``, PX4
``SYS_CAL_GYRO``) can only fit T alone. Across warm-ups that start from *different*
ambients the two separate, and the paper model F = a1·T² + a2·T + a3·ΔT + a4·T·ΔT + a5
becomes identifiable.

**Sufficient statistics, bounded memory.** Per power-on k and its rest rows i of the
warm-up (the estimator's T̂, ΔT̂; :func:`warmup_rows`), with the fixed centred basis
z = [x², x, g, x·g], x = (T̂ − 25 °C)/30 °C, g = ΔT̂/5 °C (:data:`LEARN_SCALING`), and
per axis the rate y: n, Σz, Σzzᵀ, and per axis Σy, Σzy, Σy² (:class:`WarmupStats`: 4 + 10
numbers plus 6 per axis, whatever the warm-up's length). Each power-on has its own
switch-on offset, so the slopes come from the *within*-warm-up cross-products
(S_k = Σzzᵀ − ΣzΣzᵀ/n, s_k = Σzy − ΣzΣy/n): β = (Σ_k S_k)⁻¹ Σ_k s_k; the intercept a5
is the mean offset Σ_k(Σy − Σzᵀβ)/Σ_k n (the boot-time zero removes each boot's own).

**Validation before adoption** (:func:`decide`): leave-one-power-on-out, from the same
statistics (β₋ₖ = (S − S_k)⁻¹(s − s_k); SSE_k = Syy_k − 2β₋ₖᵀs_k + β₋ₖᵀS_kβ₋ₖ), the
candidate's RMS on warm-ups it did not see against the current calibration's RMS on the
same warm-ups (``none``: no compensation), both as the *reducible* bias error: what the
model class leaves on the same warm-ups in sample (white noise, the slow noise no thermal
model removes, misfit: :func:`floor_ms`) is taken out, √max(SSE/n − floor, 0). On the raw
residual a 10 % margin could never be met by a gyro whose thermal bias moves less than
half its per-sample noise; with the white noise alone taken out (σ² from successive
differences, :func:`noise_var`), not by one whose bias instability is of the size of its
thermal bias. Adopted only when every gate passes
(:data:`GATES`: warm-ups, spread of the ambients they started from, conditioning) and the
candidate beats the current one by :data:`ADOPT_MARGIN`: on every axis when there is a
current calibration (its ranges and the learnt ones cannot be mixed in one file); per axis
when there is none (an axis whose thermal bias is below the gyro's bias instability is
left uncompensated, the others adopted); otherwise the reasons are said and learning goes
on.

**Extrapolation** (:func:`validated_extension`): the learnt calibration is clamped outside
its warm-ups' T range widened on each side by as far as the leave-one-out validation
itself extrapolated (the furthest warm-up, scored with the others' slopes), when it beat
no compensation on that warm-up (scored whole: the rows past the others' range are not
kept apart); else at the data's range, as the autopilots clamp.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._calibration import Calibration, ValidRange
from gyrotherm.compensation._effects import Effects
from gyrotherm.compensation._learn_gates import ADOPT_MARGIN, GATES, SETTLE_S, WARMUP_MAX_S
from gyrotherm.compensation._models import Scaling, get_model
from gyrotherm.estimators import EstimatorConfig

if TYPE_CHECKING:  # the fitting module is offline; the daemon's [learn] mode needs none of it
    from gyrotherm.compensation._fit import RunFeatures

FloatArray = NDArray[np.float64]

LEARN_SCALING = Scaling(t_ref_c=25.0, t_scale_c=30.0, dt_scale_c=5.0)
K = 6  # slope terms kept: x², x, g, x·g (the paper model's order), then x³, g² (effects)
#: The paper model's columns of the basis (its intercept is the per-warm-up offset).
PAPER = (0, 1, 2, 3)
#: Effects the warm-ups can show, by their calibration v2 name: the basis column each adds.
#: Warm-ups at rest only heat and only from power-on, so hysteresis, drift and a warm-up
#: transient apart from ΔT (τ ≈ the die's) are not learnable from them.
EFFECT_COLUMNS = {"cubic": 4, "gradient_quadratic": 5}
MIN_ROWS = 60
#: A log whose first row is later than this after power-on has lost its warm-up's start.
MAX_START_S = 60.0


def _z(temperature_c: FloatArray, delta_t_c: FloatArray) -> FloatArray:
    x, g = LEARN_SCALING.centre(temperature_c, delta_t_c)
    return np.column_stack([x * x, x, g, x * g, x * x * x, g * g])


def columns(effects: Sequence[str] = ()) -> tuple[int, ...]:
    """The basis columns of the paper model plus ``effects`` (:data:`EFFECT_COLUMNS`)."""
    return PAPER + tuple(EFFECT_COLUMNS[e] for e in effects)


def warmup_rows(f: RunFeatures) -> NDArray[np.bool_]:
    """The warm-up at rest: rows from SETTLE_S to WARMUP_MAX_S after power-on (``time_s``
    counts from power-on: the simulator's runs, PX4's and ArduPilot's time since boot),
    up to the first row not at rest (``f.rest``), with finite T̂ and ΔT̂."""
    t = f.time_s
    ok = (t >= SETTLE_S) & (t <= WARMUP_MAX_S)
    ok &= np.isfinite(f.temperature_c) & np.isfinite(f.delta_t_c)
    if f.rest is not None:
        moving = np.flatnonzero(~f.rest)
        if len(moving):
            ok[moving[0]:] = False
    return np.asarray(ok, dtype=np.bool_)


@dataclass(frozen=True)
class WarmupStats:
    """One power-on's sufficient statistics (module docstring)."""

    name: str
    n: int
    start_c: float
    """T̂ at the first row used: the ambient the warm-up started from, roughly."""
    t_range_c: tuple[float, float]
    dt_range_c: tuple[float, float]
    sz: tuple[float, ...]
    szz: tuple[float, ...]  # K×K, row-major
    sy: Mapping[str, float]
    szy: Mapping[str, tuple[float, ...]]
    syy: Mapping[str, float]
    sdd: Mapping[str, float]
    """Σ (y_i − y_(i−1))² over consecutive rows used (the white-noise estimate)."""
    ndd: int

    @classmethod
    def from_features(cls, f: RunFeatures, rows: NDArray[np.bool_] | None = None) -> WarmupStats:
        """The statistics of ``f``'s warm-up rows (:func:`warmup_rows` by default)."""
        if not f.time_s[0] <= MAX_START_S:
            raise CalibrationError(
                f"{f.source}: {f.name}: the log starts {f.time_s[0]:.0f} s after power-on "
                f"(time since boot), more than {MAX_START_S:g} s: its warm-up is not in it. "
                "Log from boot: PX4 SDLOG_MODE = 1 or 2, ArduPilot LOG_DISARMED = 1 (a time "
                "base that is not time since boot, such as ROS stamps, cannot be used)")
        use = warmup_rows(f) if rows is None else rows
        n = int(use.sum())
        if n < MIN_ROWS:
            span = float(f.time_s[-1] - f.time_s[0]) if len(f.time_s) else 0.0
            rate = (len(f.time_s) - 1) / span if span > 0 else 0.0
            raise CalibrationError(
                f"{f.source}: {f.name}: {n} warm-up rows at rest (at least {MIN_ROWS} "
                f"needed: from {SETTLE_S:g} s after power-on, at rest, before the first "
                f"motion); the log has {len(f.time_s)} rows over {span:.0f} s "
                f"({rate:.3g} Hz) from {f.time_s[0]:.0f} s after power-on. Log the gyro "
                "faster (PX4: SDLOG_PROFILE 'thermal calibration') and keep the vehicle "
                "still for its first minutes")
        temp, dtemp = f.temperature_c[use], f.delta_t_c[use]
        z = _z(temp, dtemp)
        ys = {a: np.asarray(r[use], dtype=np.float64) for a, r in f.rates_dps.items()}
        idx = np.flatnonzero(use)
        pairs = np.flatnonzero(np.diff(idx) == 1)  # consecutive rows both used
        dds = {a: float(np.sum(np.diff(np.asarray(r, dtype=np.float64)[idx])[pairs] ** 2))
               for a, r in f.rates_dps.items()}
        return cls(name=f.name, n=n, start_c=float(temp[0]),
                   t_range_c=(float(temp.min()), float(temp.max())),
                   dt_range_c=(float(dtemp.min()), float(dtemp.max())),
                   sz=tuple(z.sum(axis=0).tolist()), szz=tuple((z.T @ z).ravel().tolist()),
                   sy={a: float(y.sum()) for a, y in ys.items()},
                   szy={a: tuple((z.T @ y).tolist()) for a, y in ys.items()},
                   syy={a: float(y @ y) for a, y in ys.items()},
                   sdd=dds, ndd=len(pairs))

    def within(self, axis: str) -> tuple[FloatArray, FloatArray, float]:
        """(S, s, Syy): the within-warm-up cross-products of ``axis``."""
        sz = np.array(self.sz)
        s_zz = np.array(self.szz).reshape(K, K) - np.outer(sz, sz) / self.n
        s_zy = np.array(self.szy[axis]) - sz * self.sy[axis] / self.n
        return s_zz, s_zy, self.syy[axis] - self.sy[axis] ** 2 / self.n

    def sse(self, axis: str, beta: FloatArray) -> float:
        """Within-warm-up residual sum of squares of slopes ``beta`` (its own offset)."""
        s_zz, s_zy, s_yy = self.within(axis)
        return max(float(s_yy - 2.0 * beta @ s_zy + beta @ s_zz @ beta), 0.0)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "n": self.n, "start_c": self.start_c,
                "t_range_c": list(self.t_range_c), "dt_range_c": list(self.dt_range_c),
                "sz": list(self.sz), "szz": list(self.szz), "sy": dict(self.sy),
                "szy": {a: list(v) for a, v in self.szy.items()}, "syy": dict(self.syy),
                "sdd": dict(self.sdd), "ndd": self.ndd}


def slopes(stats: Sequence[WarmupStats], axis: str, cols: Sequence[int] = PAPER
           ) -> tuple[FloatArray, float]:
    """β (K slopes, LEARN_SCALING basis, zero outside ``cols``) pooled within warm-ups,
    and the condition number of the pooled cross-product of ``cols`` (scaled to unit
    diagonal)."""
    s_zz = sum((w.within(axis)[0] for w in stats), np.zeros((K, K)))
    s_zy = sum((w.within(axis)[1] for w in stats), np.zeros(K))
    return _solve(s_zz, s_zy, cols)


def _solve(s_zz: FloatArray, s_zy: FloatArray, cols: Sequence[int]) -> tuple[FloatArray, float]:
    """:func:`slopes` from pooled cross-products: columns scaled to unit diagonal, least
    squares; a cross-product that is not finite or that LAPACK cannot factor gives
    zeros and an infinite condition number (hostile sums: refused by the gate)."""
    idx = np.array(cols)
    a_zz, a_zy = s_zz[np.ix_(idx, idx)], s_zy[idx]
    beta = np.zeros(K)
    d = np.sqrt(np.maximum(np.diag(a_zz), 1e-300))
    a = a_zz / np.outer(d, d)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(a_zy))):
        return beta, math.inf
    try:
        cond = float(np.linalg.cond(a))
        sub, *_ = np.linalg.lstsq(a, a_zy / d, rcond=1e-12)
    except np.linalg.LinAlgError:
        return beta, math.inf
    beta[idx] = sub / d
    return beta, cond


class _Folds:
    """Leave-one-warm-up-out slopes of one axis from the pooled cross-products, each
    β₋ₖ solved from (S − S_k, s − s_k): O(warm-ups) per set of columns, not O(warm-ups²)
    (256 warm-ups: what the daemon may hold)."""

    def __init__(self, stats: Sequence[WarmupStats], axis: str) -> None:
        parts = [w.within(axis) for w in stats]
        self.s_k = np.array([p[0] for p in parts]).reshape(len(stats), K, K)
        self.v_k = np.array([p[1] for p in parts]).reshape(len(stats), K)
        self.s, self.v = self.s_k.sum(axis=0), self.v_k.sum(axis=0)
        self._beta: dict[tuple[int, tuple[int, ...]], FloatArray] = {}

    def beta(self, k: int, cols: Sequence[int]) -> FloatArray:
        key = (k, tuple(cols))
        if key not in self._beta:
            self._beta[key] = _solve(self.s - self.s_k[k], self.v - self.v_k[k], cols)[0]
        return self._beta[key]


def intercept(stats: Sequence[WarmupStats], axis: str, beta: FloatArray) -> float:
    """The mean switch-on offset under slopes ``beta`` (°/s): the calibration's a5."""
    total = sum(w.sy[axis] - float(np.array(w.sz) @ beta) for w in stats)
    return total / sum(w.n for w in stats)


def basis_slopes(cal: Calibration | None, axis: str) -> FloatArray:
    """A paper calibration's slopes in LEARN_SCALING's basis, its ``cubic`` and
    ``gradient_quadratic`` effects included (the same polynomial space: exact up to
    rounding; its other effects are not in the basis and are left out); zeros for
    ``None`` (no compensation)."""
    if cal is None:
        return np.zeros(K)
    if cal.model.name != "paper":
        raise CalibrationError(f"learning compares against a paper-model calibration, "
                               f"not {cal.model.name!r}")
    grid_t, grid_d = np.meshgrid(np.linspace(-20.0, 70.0, 7), np.linspace(-10.0, 10.0, 5))
    t, d = grid_t.ravel(), grid_d.ravel()
    y = cal.base_series(axis, t, d)  # unclamped polynomial (base_series does not clamp)
    eff = cal.effects.get(axis)
    if eff is not None and eff.cubic is not None:
        y = y + eff.cubic.coefficient_dps_per_c3 * (t - eff.cubic.t_ref_c) ** 3
    if eff is not None and eff.gradient_quadratic is not None:
        y = y + eff.gradient_quadratic.coefficient_dps_per_c2 * d * d
    z = np.column_stack([_z(t, d), np.ones(len(t))])
    coef, *_ = np.linalg.lstsq(z, y, rcond=None)
    return np.asarray(coef[:K], dtype=np.float64)


@dataclass(frozen=True)
class Decision:
    """What :func:`decide` found: adopt or not, why, and the validation figures."""

    adopt: bool
    reasons: tuple[str, ...]
    warmups: int
    start_span_c: float
    condition: float
    candidate_rms_dps: Mapping[str, float] = field(default_factory=dict)
    current_rms_dps: Mapping[str, float] = field(default_factory=dict)
    axes_adopted: tuple[str, ...] = ()
    """The axes whose learnt model is used (all of them, or per axis without a current)."""
    effects: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    """Per axis, the effects (:data:`EFFECT_COLUMNS`) the held-out warm-ups chose."""
    margin: float = ADOPT_MARGIN
    """The margin it decided with (:func:`validated_extension` uses the same)."""

    def to_dict(self) -> dict[str, Any]:
        return {"adopt": self.adopt, "axes_adopted": list(self.axes_adopted),
                "effects": {a: list(e) for a, e in self.effects.items() if e},
                "margin": self.margin,
                "reasons": list(self.reasons), "warmups": self.warmups,
                "start_span_c": self.start_span_c, "condition": self.condition,
                "candidate_heldout_rms_dps": dict(self.candidate_rms_dps),
                "current_heldout_rms_dps": dict(self.current_rms_dps)}


def heldout_rms(stats: Sequence[WarmupStats], axis: str,
                fixed: FloatArray | None = None, scored: Sequence[int] | None = None,
                cols: Sequence[int] = PAPER) -> float:
    """RMS on each warm-up of slopes (basis columns ``cols``) fitted without it
    (``fixed``: the same slopes for every warm-up, a calibration learnt elsewhere),
    offsets removed per warm-up; over the warm-ups ``scored`` (indices; default all),
    the fits still using all the others."""
    sse, n = 0.0, 0
    folds = _Folds(stats, axis) if fixed is None else None
    for k in range(len(stats)) if scored is None else scored:
        beta = folds.beta(k, cols) if folds is not None else fixed
        assert beta is not None
        sse += stats[k].sse(axis, beta)
        n += stats[k].n
    return math.sqrt(sse / n)


def unseen(stats: Sequence[WarmupStats], current: Calibration | None) -> list[int]:
    """Indices of the warm-ups ``current`` was not learnt from (its provenance's
    ``power_ons``): all of them for a chamber calibration or none."""
    record = current.provenance if current is not None else {}
    used = {p.get("name") for p in record.get("power_ons", ()) if isinstance(p, Mapping)}
    return [k for k, w in enumerate(stats) if w.name not in used]


def noise_var(stats: Sequence[WarmupStats], axis: str) -> float:
    """White-noise variance of ``axis`` (°/s)², from successive differences."""
    n = sum(w.ndd for w in stats)
    return sum(w.sdd[axis] for w in stats) / (2.0 * n) if n else 0.0


def floor_ms(stats: Sequence[WarmupStats], axis: str,
             scored: Sequence[int] | None = None) -> float:
    """What the model class leaves on the warm-ups ``scored`` fitted on all of ``stats``
    (in sample, offsets removed per warm-up), mean square (°/s)²: white noise, the slow
    noise no thermal model removes (bias instability, rate random walk) and the part of
    the bias the richest model (the paper model and every effect) cannot express."""
    beta = slopes(stats, axis, tuple(range(K)))[0]
    ks = range(len(stats)) if scored is None else scored
    n = sum(stats[k].n for k in ks)
    return sum(stats[k].sse(axis, beta) for k in ks) / n if n else 0.0


def heldout_bias_rms(stats: Sequence[WarmupStats], axis: str,
                     fixed: FloatArray | None = None, scored: Sequence[int] | None = None,
                     cols: Sequence[int] = PAPER) -> float:
    """:func:`heldout_rms` with what no calibration can remove taken out: the RMS of the
    *reducible* bias error, √max(MSE_held-out − :func:`floor_ms`, 0) (°/s).

    Taking out the white noise alone (σ² from successive differences, :func:`noise_var`)
    leaves the gyro's slow noise in both sides of :func:`decide`'s comparison: with a
    bias instability of 0.006 °/s against a thermal bias of 0.009 °/s a margin of 10 %
    could then never be met (docs/findings.md §8)."""
    rms = heldout_rms(stats, axis, fixed, scored, cols)
    return math.sqrt(max(rms * rms - floor_ms(stats, axis, scored), 0.0))


def choose_effects(stats: Sequence[WarmupStats], axis: str, scored: Sequence[int], *,
                   margin: float = ADOPT_MARGIN) -> tuple[tuple[str, ...], float, str]:
    """The effects ``axis``' held-out warm-ups support: of the paper model alone and with
    each subset of :data:`EFFECT_COLUMNS` (well conditioned), the one with the least
    held-out bias error, taken only when it beats the paper model alone by ``margin``
    overall and on enough warm-ups one by one (:data:`EFFECT_SIGN_P`: one warm-up's slow
    noise can carry the pooled margin); (effects, its held-out bias RMS, a sentence
    saying so or "")."""
    paper = heldout_bias_rms(stats, axis, scored=scored)
    best: tuple[tuple[str, ...], float] = ((), paper)
    for effects in (("cubic",), ("gradient_quadratic",), ("cubic", "gradient_quadratic")):
        cols = columns(effects)
        if not slopes(stats, axis, cols)[1] <= GATES["max_condition"]:
            continue
        rms = heldout_bias_rms(stats, axis, scored=scored, cols=cols)
        if rms < best[1]:
            best = (effects, rms)
    if not best[0] or best[1] > (1.0 - margin) * paper:
        return (), paper, ""
    folds = _Folds(stats, axis)
    wins = sum(_fold_sse(stats, folds, axis, k, columns(best[0]))
               < _fold_sse(stats, folds, axis, k, PAPER) for k in scored)
    p = _sign_p(wins, len(scored))
    if p > EFFECT_SIGN_P:
        return (), paper, (f"{axis}: {' and '.join(best[0])} not learnt: better on "
                           f"{wins} of {len(scored)} held-out warm-ups (sign test p = "
                           f"{p:.2g} > {EFFECT_SIGN_P:g})")
    return best[0], best[1], (f"{axis}: {' and '.join(best[0])} learnt (held-out bias "
                              f"error {paper:.4g} → {best[1]:.4g} °/s, better on {wins} of "
                              f"{len(scored)} warm-ups, sign test p = {p:.2g})")


#: An effect is learnt only when it is better on so many held-out warm-ups that chance
#: would do as well with at most this probability (one-sided sign test, 5 % shared by the
#: three subsets tried — the best of three is tested — so 9 of 10 warm-ups, 22 of 30;
#: never with fewer than 6).
EFFECT_SIGN_P = 0.05 / 3


def _fold_sse(stats: Sequence[WarmupStats], folds: _Folds, axis: str, k: int,
              cols: Sequence[int]) -> float:
    return stats[k].sse(axis, folds.beta(k, cols))


def _sign_p(wins: int, n: int) -> float:
    """P(at least ``wins`` of ``n`` fair coin tosses)."""
    return sum(math.comb(n, i) for i in range(wins, n + 1)) / 2.0 ** n if n else 1.0


def decide(stats: Sequence[WarmupStats], current: Calibration | None,
           axes: Sequence[str], *, margin: float = ADOPT_MARGIN,
           min_warmups: int | None = None, min_start_span_c: float | None = None
           ) -> Decision:
    """Whether the calibration learnt from ``stats`` should replace ``current``;
    ``min_warmups`` and ``min_start_span_c`` override :data:`GATES` (the daemon's
    ``[learn]`` table; at least 3 warm-ups are always needed)."""
    reasons: list[str] = []
    span = (max(w.start_c for w in stats) - min(w.start_c for w in stats)) if stats else 0.0
    need_n = max(int(GATES["min_warmups"]), min_warmups or 0)
    need_span = GATES["min_start_span_c"] if min_start_span_c is None else min_start_span_c
    if len(stats) < need_n:
        reasons.append(f"warm-ups: {len(stats)} at rest, at least {need_n:g} "
                       "needed (one is held out at a time)")
    if span < need_span:
        reasons.append(f"start temperatures span {span:.1f} °C, at least "
                       f"{need_span:g} °C needed (T and ΔT move together "
                       "within one warm-up; only different ambients separate them)")
    if reasons:
        return Decision(False, tuple(reasons), len(stats), span, math.inf)
    cond = max(slopes(stats, a)[1] for a in axes)
    if not cond <= GATES["max_condition"]:
        return Decision(False, (f"conditioning: {cond:.3g} > {GATES['max_condition']:g}",),
                        len(stats), span, cond)
    # the current calibration is scored only on warm-ups it was not learnt from (a
    # learnt one would otherwise be judged on its own training data), the candidate on
    # the same ones, each fitted without the one it is scored on
    fresh = unseen(stats, current)
    if not fresh:
        return Decision(False, ("held-out warm-ups: none that the current calibration was "
                                "not learnt from: it is kept until a new one comes",),
                        len(stats), span, cond)
    chosen = {a: choose_effects(stats, a, fresh, margin=margin) for a in axes}
    cand = {a: chosen[a][1] for a in axes}
    cur = {a: heldout_bias_rms(stats, a, basis_slopes(current, a), fresh) for a in axes}
    better = tuple(a for a in axes if cand[a] <= (1.0 - margin) * cur[a])
    worse = [a for a in axes if a not in better]
    what = "no compensation" if current is None else "the current calibration"
    if better:
        reasons.append(f"held-out warm-ups, bias error: better than {what} by ≥ "
                       f"{100 * margin:g} % on {', '.join(better)} (" + ", ".join(
                           f"{a}: {cand[a]:.4g} vs {cur[a]:.4g} °/s" for a in better) + ")")
    if worse:
        reasons.append(f"held-out warm-ups, bias error: not better than {what} by "
                       f"{100 * margin:g} % on {', '.join(worse)} (" + ", ".join(
                           f"{a}: {cand[a]:.4g} vs {cur[a]:.4g} °/s" for a in worse) + ")"
                       + ("" if current is None else ": the current calibration is kept"))
    adopted = better if current is None else (tuple(axes) if not worse else ())
    reasons += [chosen[a][2] for a in adopted if chosen[a][2]]  # learnt, or why not
    return Decision(bool(adopted), tuple(reasons), len(stats), span, cond, cand, cur,
                    adopted, {a: chosen[a][0] for a in adopted}, margin)


def validated_extension(stats: Sequence[WarmupStats], axes: Sequence[str], *,
                        margin: float = ADOPT_MARGIN,
                        effects: Mapping[str, Sequence[str]] | None = None
                        ) -> tuple[float, float]:
    """How far (°C, below and above) the learnt T range may be used unclamped: as far as
    the leave-one-power-on-out validation itself extrapolated, and no further.

    On each side, the warm-up that reaches furthest (coldest minimum, hottest maximum) is
    scored with the slopes of the others, unclamped, ``overhang`` °C past their range (as
    :func:`decide` scores it when it is held out). That overhang counts as validated when,
    on every axis of ``axes``, its bias error over the whole warm-up (the statistics keep
    no rows: its part past the others' range is not scored apart) beat no compensation by
    ``margin``
    (:func:`heldout_bias_rms` scored on that warm-up alone); else 0 (the range stays the
    data's, clamped, like the autopilots'). Each axis is scored with its ``effects``.
    With fewer than 3 warm-ups, (0, 0)."""
    eff = effects or {}
    if len(stats) < 3 or not axes:
        return 0.0, 0.0
    out = []
    for side in (0, 1):
        ends = [w.t_range_c[side] for w in stats]
        k = int(np.argmin(ends) if side == 0 else np.argmax(ends))
        others = [e for j, e in enumerate(ends) if j != k]
        overhang = (min(others) - ends[k]) if side == 0 else (ends[k] - max(others))
        ok = overhang > 0 and all(
            0.0 < (none := heldout_bias_rms(stats, a, np.zeros(K), [k]))
            and heldout_bias_rms(stats, a, scored=[k], cols=columns(eff.get(a, ())))
            <= (1.0 - margin) * none
            for a in axes)
        out.append(float(overhang) if ok else 0.0)
    return out[0], out[1]


def learnt_calibration(stats: Sequence[WarmupStats], axes: Sequence[str], *,
                       estimator: EstimatorConfig, decision: Decision | None = None,
                       provenance: Mapping[str, Any] | None = None) -> Calibration:
    """The paper-model calibration the warm-ups give (LEARN_SCALING), with provenance:
    the power-ons used, the temperature coverage, the validation figures.

    Its valid T range (clamped outside, flagged) is the coverage of the warm-ups widened
    by :func:`validated_extension` (``validated_extrapolation_c`` in the provenance;
    ``coverage_c`` stays the data's)."""
    coefficients: dict[str, tuple[float, ...]] = {}
    chosen = decision.effects if decision is not None else {}
    effects: dict[str, Effects] = {}
    for a in axes:
        if decision is not None and a not in decision.axes_adopted:
            coefficients[a] = (0.0,) * (len(PAPER) + 1)  # not learnt well: no compensation
            continue
        beta = slopes(stats, a, columns(chosen.get(a, ())))[0]
        coefficients[a] = (*(float(b) for b in beta[:len(PAPER)]),
                           float(intercept(stats, a, beta)))
        if chosen.get(a):
            effects[a] = _effects(beta, chosen[a])
    lo_c, hi_c = min(w.t_range_c[0] for w in stats), max(w.t_range_c[1] for w in stats)
    used = [a for a in axes if decision is None or a in decision.axes_adopted]
    below_c, above_c = validated_extension(
        stats, used, effects=chosen,
        margin=decision.margin if decision is not None else ADOPT_MARGIN)
    rng = ValidRange(lo_c - below_c, hi_c + above_c,
                     min(w.dt_range_c[0] for w in stats), max(w.dt_range_c[1] for w in stats))
    record = {"method": "learnt from warm-ups at rest, one offset per power-on",
              "power_ons": [{"name": w.name, "rows": w.n, "start_c": w.start_c,
                             "t_range_c": list(w.t_range_c)} for w in stats],
              "coverage_c": [lo_c, hi_c],
              "validated_extrapolation_c": [below_c, above_c],
              **({"validation": decision.to_dict()} if decision else {}),
              **(provenance or {})}
    return Calibration(model=get_model("paper"), scaling=LEARN_SCALING,
                       coefficients=coefficients, valid_range=rng, estimator=estimator,
                       provenance=record, effects=effects)


def _effects(beta: FloatArray, names: Sequence[str]) -> Effects:
    """The calibration v2 effects of slopes ``beta``: x³ = (T − 25)³/30³ and g² = ΔT²/5²
    in :data:`LEARN_SCALING`, exactly."""
    t = LEARN_SCALING
    params: dict[str, dict[str, float]] = {}
    if "cubic" in names:
        params["cubic"] = {"coefficient_dps_per_c3": float(beta[4]) / t.t_scale_c ** 3,
                           "t_ref_c": t.t_ref_c}
    if "gradient_quadratic" in names:
        params["gradient_quadratic"] = {
            "coefficient_dps_per_c2": float(beta[5]) / t.dt_scale_c ** 2}
    return Effects.from_params(params)


__all__ = ["ADOPT_MARGIN", "EFFECT_COLUMNS", "GATES", "LEARN_SCALING", "PAPER", "SETTLE_S",
           "WARMUP_MAX_S", "Decision", "WarmupStats", "choose_effects", "columns", "decide",
           "floor_ms", "heldout_bias_rms", "heldout_rms", "learnt_calibration", "noise_var",
           "unseen", "validated_extension", "warmup_rows"]
