"""Null replays: what a fitted ``thermal_lag`` looks like when no lag exists.

A quantised, held temperature reading is a staircase; the diagnosis' smoothed
temperature keeps a ripple of up to ~LSB/2 between code changes, and the bias'
temperature terms carry that ripple into the residuals. A first-order lag of
the temperature smooths the ripple away, so a lag buys held-out gain where the
physics has none. How much, and at which τ, depends on the readout (LSB, hold
period, white noise), the ramp rates and the device's temperature sensitivity,
so it is measured on replays of the runs themselves:

1. **A temperature without the readout's steps.** When the runs log the
   chamber, the case temperature the chamber drives: T = lowpass(chamber + P, τ)
   with τ and the self-heating P regressed from the runs (:func:`~._prep.fit_tau`;
   the thermal physics the estimator already assumes), shifted to the reading's
   mean. Without a chamber, a zero-phase Savitzky–Golay fit of the reading over
   max(121 s, 4 LSB crossings) (smoother at the corners: the replay then
   underestimates what the readout produces, and says so in the verdict).
2. **The model without the lag, fitted on that temperature.** Fitted on the
   staircase, the temperature coefficients are attenuated (errors in the
   variable) and a replay built from them understates the ripple the bias
   terms carry; so the coefficients are refitted to the measured rates on the
   step-free temperature. The replayed rate is that model plus white noise of
   its residuals' spread (``noise="white"``), or, for the shape check's power
   only (:mod:`._shape_check`), plus noise with its residuals' spectrum as well
   (``noise="coloured"``, :func:`surrogate`; round 11 of issue 19).
3. **The same readout.** The step-free temperature is re-read as the sensor
   does (refreshed every hold period, white noise σ as characterised, rounded
   to the LSB, held; 1-s block means) and smoothed like the real reading.

On each replay the model without the lag and the model with a lag (τ searched
as in the selection) are scored leave-one-run-out; the null gain and the null
lag's τ are what the readout alone produces (:func:`replay_lag`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from gyrotherm.analysis._effects import design, lowpass
from gyrotherm.analysis._prep import Prepared, Readout, _smooth, fit_tau
from gyrotherm.analysis._score import Evaluation, Selector

FloatArray = NDArray[np.float64]

REPLAY_SUBSTEP_S = 0.1
"""Sub-sample spacing (s) of the replayed readout within each 1-s block."""
TRUTH_WINDOW_S = 121
"""Window (s, odd) of the zero-phase fit that gives the step-free temperature without a chamber."""

Noise = Literal["white", "coloured"]
"""The replayed rate's noise: ``"white"``, white noise of the model's residuals' spread
(every null replay); ``"coloured"``, per run a phase-randomised surrogate of the model's
residuals (:func:`surrogate`: the same variance and autocorrelation). A MEMS gyro's bias
wanders (bias instability, rate random walk), so its residuals are correlated over
minutes: on white replays a spline's extra columns are cheaper held out than on the runs,
and the shape check's power is overstated (round 10 of issue 19). On the null replays
coloured noise was tried and lowered what the readout alone buys a lag, so there white
noise is kept: the larger null (docs/findings.md §6, rounds 10 and 11)."""


@dataclass(frozen=True)
class LagReplay:
    """Held-out gains of a ``thermal_lag`` on the runs and on null replays."""

    real_gain: float
    null_gains: tuple[float, ...]
    null_tau_s: tuple[float, ...]
    truth: str
    """How the step-free temperature was made: ``"chamber"`` or ``"smoothed reading"``."""

    @property
    def null_gain(self) -> float:
        return max(self.null_gains)

    @property
    def null_tau(self) -> float:
        return float(np.median(self.null_tau_s))


def _pseudo_truth(temperature_c: FloatArray, crossing_s: float) -> FloatArray:
    """A zero-phase Savitzky–Golay fit (order 2) over max(121 s, 4 LSB crossings)."""
    n = len(temperature_c)
    w = int(max(TRUTH_WINDOW_S, 4.0 * crossing_s)) | 1
    w = min(w, n - 1 if n % 2 == 0 else n)
    if w < 5:
        return temperature_c.copy()
    return np.asarray(savgol_filter(temperature_c, w, 2, mode="interp"), dtype=np.float64)


def step_free(runs: Sequence[Prepared], crossing_s: float) -> tuple[list[FloatArray], str]:
    """Step 1 of the module docstring, per run, and which construction was used."""
    chamber = fit_tau(runs)
    if chamber is None or any(p.chamber_c is None for p in runs):
        return [_pseudo_truth(p.temperature_c, crossing_s) for p in runs], "smoothed reading"
    tau, heat = chamber
    out = []
    for p in runs:
        assert p.chamber_c is not None
        t = lowpass(p.chamber_c + heat, tau, step_s=float(np.median(np.diff(p.time_s))))
        out.append(np.asarray(t + np.mean(p.temperature_c - t), dtype=np.float64))
    return out, "chamber"


def reread(
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


def replay_readout(readouts: Sequence[Readout]) -> Readout:
    """The runs' readout for the replay: median hold and LSB; the white noise σ as
    characterised (before rounding), not the scatter between changes (which, at a
    coarse LSB, is one LSB step and would dither away the staircase)."""
    white = [r.white_noise_c if r.refresh_period_s > 0 else r.noise_c for r in readouts]
    return replace(readouts[0],
                   period_s=float(np.median([r.period_s for r in readouts])),
                   lsb_c=float(np.median([r.lsb_c for r in readouts])),
                   noise_c=float(np.median(white)))


Columns = Callable[[FloatArray], Sequence[FloatArray]]
"""ΔT (°C) → candidate columns of an alternative shape (e.g. tanh(ΔT/s) for several s)."""


@dataclass(frozen=True)
class Alternative:
    """An effect of the runs' model replaced, in the replays' generating model, by another
    shape in ΔT of the same size: the model with ``effect`` (name → nonlinear parameter)
    is fitted on the step-free runs, and its prediction is refitted jointly by the other
    effects' columns (at that fit's nonlinear parameters) and one candidate column of
    ``columns`` (per-run offsets free); the candidate that fits the prediction closest is
    generated in the effect's place, with the other columns at their refitted values
    (:func:`_alternative`)."""

    effect: Mapping[str, float]
    columns: Columns


def surrogate(residual: FloatArray, rng: np.random.Generator) -> FloatArray:
    """A phase-randomised surrogate of ``residual`` (its mean removed): the same amplitude
    spectrum, so the same variance and (circular) autocorrelation, with uniformly random
    Fourier phases (the mean and, for an even length, the Nyquist term kept real)."""
    r = np.asarray(residual, dtype=np.float64) - float(np.mean(residual))
    spectrum = np.fft.rfft(r)
    phase = rng.uniform(0.0, 2.0 * np.pi, len(spectrum))
    phase[0] = 0.0
    if len(r) % 2 == 0:
        phase[-1] = 0.0
    return np.asarray(np.fft.irfft(np.abs(spectrum) * np.exp(1j * phase), len(r)),
                      dtype=np.float64)


def _alternative(
    true_sel: Selector, rest: Mapping[str, float], alt: Alternative
) -> tuple[dict[str, float], FloatArray, list[FloatArray], float, list[FloatArray]]:
    """The generating model with the alternative (:class:`Alternative`): the other
    effects (name → nonlinear parameter, as fitted with the effect), their columns'
    coefficients, the alternative's column per run (amplitude in it), and the white
    noise (°/s) and the residuals (°/s, per run) of the model with the effect.

    With the catalogued form itself as the only candidate, the generating model is the
    model with the effect (to rounding; tests/analysis/test_shape_power.py)."""
    from gyrotherm.analysis._select import _refine_all

    full = _refine_all(true_sel, true_sel.evaluate({**rest, **alt.effect}))
    others = {k: v for k, v in full.effects.items() if k not in alt.effect}
    target = np.concatenate([
        (p.rate_dps - p.rate_dps.mean()) - r
        for p, r in zip(true_sel.runs, true_sel.residuals(full.effects, full.coefficients),
                        strict=True)])
    xs = []
    for p in true_sel.runs:
        _, x = design(p.time_s, p.temperature_c, p.delta_t_c, true_sel.scaling, others)
        xs.append(x - x.mean(axis=0))
    cands = [alt.columns(p.delta_t_c) for p in true_sel.runs]
    best: tuple[float, FloatArray, list[FloatArray]] | None = None
    for k in range(len(cands[0])):
        cols = [np.asarray(c[k], dtype=np.float64) for c in cands]
        m = np.vstack([np.column_stack([x, c - c.mean()]) for x, c in zip(xs, cols,
                                                                          strict=True)])
        coef, *_ = np.linalg.lstsq(m, target, rcond=None)
        miss = float(np.sum((target - m @ coef) ** 2))
        if best is None or miss < best[0]:
            best = (miss, np.asarray(coef[:-1], dtype=np.float64), [coef[-1] * c for c in cols])
    assert best is not None
    return (others, best[1], best[2], float(np.sqrt(full.rss / full.n)),
            true_sel.residuals(full.effects, full.coefficients))


def step_free_selector(selector: Selector, crossing_s: float) -> tuple[Selector, float]:
    """The runs on their step-free temperature (step 1 of the module docstring; ΔT = τ·dT/dt
    of it, with the runs' τ) as a selector, and that τ (s)."""
    tau = float(np.median([np.median(p.delta_t_c[p.rate_c_per_s != 0]
                                     / p.rate_c_per_s[p.rate_c_per_s != 0])
                           for p in selector.runs]))
    truths, _ = step_free(selector.runs, crossing_s)
    true_runs = []
    for p, t in zip(selector.runs, truths, strict=True):
        rate = np.gradient(t, p.time_s)
        true_runs.append(replace(p, temperature_c=t, rate_c_per_s=rate, delta_t_c=tau * rate))
    return Selector(true_runs, selector.scaling), tau


def _with_splines(
    true_sel: Selector, effects: Mapping[str, float], splines: Sequence[tuple[str, FloatArray]]
) -> tuple[FloatArray, list[FloatArray], float, list[FloatArray]]:
    """The generating model ``effects`` plus the linear ``splines`` (variable, knots) fitted
    jointly on the step-free runs (:func:`~._unexplained.evaluate_with`, one offset per
    run): the effects' column coefficients, the splines' sum per run (°/s), the residuals'
    spread (°/s) and the residuals per run (°/s)."""
    from gyrotherm.analysis._unexplained import evaluate_with, hats, variable

    ev = evaluate_with(true_sel, effects, splines)
    n_model = len(ev.columns) - sum(len(k) - 1 for _, k in splines)
    extra, residuals = [], []
    for p in true_sel.runs:
        _, x = design(p.time_s, p.temperature_c, p.delta_t_c, true_sel.scaling, effects)
        add = np.zeros(len(p))
        start = n_model
        for v, k in splines:
            add += hats(variable(p, v), k)[:, 1:] @ ev.coefficients[start: start + len(k) - 1]
            start += len(k) - 1
        extra.append(add)
        fit = x @ ev.coefficients[:n_model] + add
        r = (p.rate_dps - fit) - float(np.mean(p.rate_dps - fit))
        residuals.append(np.asarray(r, dtype=np.float64))
    return (np.asarray(ev.coefficients[:n_model], dtype=np.float64), extra,
            float(np.sqrt(ev.rss / ev.n)), residuals)


def _null_selectors(
    selector: Selector, rest: dict[str, float], readouts: Sequence[Readout], crossing_s: float,
    *, seed: int, replays: int, unresolved: Mapping[str, float] | None = None,
    alternative: Alternative | None = None, noise: Noise = "white",
    splines: Sequence[tuple[str, FloatArray]] = (),
) -> Iterator[Selector]:
    """``replays`` readout replays of the runs with the model ``rest`` (module docstring,
    steps 1–3), each as a selector on the replayed runs; ``unresolved`` effects (name →
    nonlinear parameter) are added to the generating model where ``rest`` lacks them;
    ``alternative``: its shape of the same size as its effect is added (:class:`Alternative`);
    ``noise``: the replayed rate's noise (:data:`Noise`); ``splines`` (variable, knots):
    unexplained structures in the generating model, each a linear spline in the step-free
    runs' own variable (T, ΔT = τ·dT/dt of the step-free temperature, or time), fitted with
    the model on the step-free runs (:func:`_with_splines`; not with ``alternative``)."""
    from gyrotherm.analysis._select import _refine_all

    rest = {**(unresolved or {}), **rest}
    true_sel, tau = step_free_selector(selector, crossing_s)
    true_runs = true_sel.runs
    extra = [np.zeros(len(p)) for p in true_runs]
    if alternative is None:
        model = _refine_all(true_sel, true_sel.evaluate(rest))
        effects, coefficients = dict(model.effects), model.coefficients
        if splines:  # the structures fitted with the model: its spread and residuals
            coefficients, extra, sd_dps, residuals = _with_splines(true_sel, effects, splines)
        else:
            sd_dps = float(np.sqrt(model.rss / model.n))
            residuals = (true_sel.residuals(model.effects, model.coefficients)
                         if noise == "coloured" else [])
    elif splines:
        raise ValueError("_null_selectors: splines with an alternative are not supported")
    else:
        effects, coefficients, extra, sd_dps, residuals = _alternative(true_sel, rest,
                                                                       alternative)
    readout = replay_readout(readouts)
    rng = np.random.default_rng(seed)
    for _ in range(replays):
        replayed: list[Prepared] = []
        for i, (p, tp, add) in enumerate(zip(selector.runs, true_runs, extra, strict=True)):
            _, x = design(tp.time_s, tp.temperature_c, tp.delta_t_c, selector.scaling,
                          effects)
            wander = (surrogate(residuals[i], rng) if noise == "coloured"
                      else rng.standard_normal(len(p)) * sd_dps)
            y = x @ coefficients + add + wander
            temp, rate_c = _smooth(reread(p.time_s, tp.temperature_c, readout, rng))
            replayed.append(replace(p, temperature_c=temp, rate_c_per_s=rate_c,
                                    delta_t_c=tau * rate_c, rate_dps=y))
        yield Selector(replayed, selector.scaling)


def replay_lag(
    selector: Selector, final: Evaluation, readouts: Sequence[Readout], crossing_s: float,
    *, seed: int = 0, replays: int = 2, effect: str = "thermal_lag",
) -> LagReplay:
    """Real and null held-out gains of ``final``'s ``effect`` (a ``thermal_lag`` unless
    told otherwise; module docstring)."""
    from gyrotherm.analysis._effects import TAU_GRIDS
    from gyrotherm.analysis._select import _refine_all

    rest = {k: v for k, v in final.effects.items() if k != effect}
    without = _refine_all(selector, selector.evaluate(rest))
    real = without.heldout_rms_dps / final.heldout_rms_dps
    _, how = step_free(selector.runs, crossing_s)
    gains, taus = [], []
    for null_sel in _null_selectors(selector, rest, readouts, crossing_s, seed=seed,
                                    replays=replays):
        null_without = _refine_all(null_sel, null_sel.evaluate(rest))
        search = effect if effect in TAU_GRIDS else None
        null_with = _refine_all(null_sel, null_sel.evaluate({**rest, effect: 0.0},
                                                            search=search))
        gains.append(null_without.heldout_rms_dps / null_with.heldout_rms_dps)
        taus.append(float(null_with.effects[effect]))
    return LagReplay(real, tuple(gains), tuple(taus), how)


def replay_spline(
    selector: Selector, effects: dict[str, float], readouts: Sequence[Readout],
    crossing_s: float, variable: str, *, seed: int = 0, replays: int = 2,
    unresolved: Mapping[str, float] | None = None,
    others: Sequence[tuple[str, FloatArray]] = (),
) -> tuple[tuple[float, ...], str]:
    """Null held-out gains of an unexplained spline in ``variable`` (:mod:`._unexplained`)
    on readout replays of the model ``effects`` without it: on each replay the best
    ratio of the model's held-out RMS to that with the spline added, or in place of one
    of the effects (as the search tries it); and how the step-free temperature was made.

    ``unresolved``: effects the diagnosis left out as not resolvable (name → nonlinear
    parameter). They are in the replays' generating model, at their size fitted on the
    step-free temperature, but not in the model fitted to the replays, as on the runs:
    the null is then what the readout gives plus what the data could not resolve, so a
    spline that only stands in for a left-out hysteresis, lag or drift is not reported
    in its place.

    ``others`` (variable, knots): the other unexplained structures found beside it. They
    are in the replays' generating model, each a spline in the step-free runs' own variable
    at its size fitted there (:func:`_with_splines`), and in the model fitted to the
    replays, each a spline of the same knot count in the replay's estimated variable, as on
    the runs, where the structure's gain is over the model with them (round 15 of issue 19:
    a structure in ΔT read through a 1 °C readout is fitted in an estimated ΔT that lags and
    smears the true one; what its spline then leaves follows the temperature profile, which
    every run repeats at the same times since power-on, and a spline in time took it)."""
    gains, how = replay_splines(selector, effects, readouts, crossing_s, (variable,),
                                seed=seed, replays=replays, unresolved=unresolved,
                                others=others)
    return gains[variable], how


def replay_splines(
    selector: Selector, effects: dict[str, float], readouts: Sequence[Readout],
    crossing_s: float, variables: Sequence[str], *, seed: int = 0, replays: int = 2,
    unresolved: Mapping[str, float] | None = None,
    others: Sequence[tuple[str, FloatArray]] = (),
) -> tuple[dict[str, tuple[float, ...]], str]:
    """:func:`replay_spline` for each of ``variables`` on the same replays (the replays
    depend on ``seed``, not on the variable, so each variable's gains are those
    :func:`replay_spline` gives it alone)."""
    from gyrotherm.analysis._unexplained import evaluate_with, knots_for, spline_knots

    _, how = step_free(selector.runs, crossing_s)
    gains: dict[str, list[float]] = {v: [] for v in variables}
    for null_sel in _null_selectors(selector, dict(effects), readouts, crossing_s, seed=seed,
                                    replays=replays, unresolved=unresolved, splines=others):
        fitted = [(w, knots_for(null_sel.runs, w, len(k))) for w, k in others]
        before = evaluate_with(null_sel, effects, fitted)
        for variable in variables:
            knots = spline_knots(null_sel, effects, fitted, variable, before)  # as the search
            trials = [evaluate_with(null_sel, {k: v for k, v in effects.items() if k != name},
                                    [*fitted, (variable, knots)]) for name in ("", *effects)]
            gains[variable].append(before.heldout_rms_dps
                                   / min(t.heldout_rms_dps for t in trials))
    return {v: tuple(g) for v, g in gains.items()}, how


def replay_shape(
    selector: Selector, effects: dict[str, float], readouts: Sequence[Readout],
    crossing_s: float, name: str, variable: str, n_knots: int, *,
    splines: Sequence[tuple[str, int]] = (), unresolved: Mapping[str, float] | None = None,
    seed: int = 0, replays: int = 2, alternative: Columns | None = None,
    noise: Noise = "white",
) -> tuple[float, ...]:
    """Null ratios of the shape check (:mod:`._shape_check`) for the catalogued ``name``:
    on readout replays of the model ``effects`` — ``name`` in its catalogued form, so
    the null is "the shape is the catalogue's" — the held-out RMS with ``name`` over
    that with a linear spline in ``variable`` (``n_knots`` knots over the replay's range)
    in its place. Read through a coarse readout, even an exact c·ΔT² or s·t is fitted
    better by a spline in the estimated variable (errors in the variable bend it), so
    the runs' ratio must beat these.

    As on the runs: the effects' nonlinear parameters are refitted on each replay, the
    unexplained ``splines`` already reported (variable, knot count) are fitted in both
    models, and the effects left out as not resolvable (``unresolved``) are in the
    replays' generating model only (:func:`replay_spline`).

    ``alternative``: the check's power instead of its null. ``name`` is generated as
    the closest of these shapes in ΔT of the same size (:class:`Alternative`), and the
    model fitted to the replays still has ``name`` in its catalogued form: the ratios
    say whether the check tells that shape from the catalogue's at this readout.

    ``noise``: the replayed rate's noise (:data:`Noise`)."""
    from gyrotherm.analysis._select import _refine_all
    from gyrotherm.analysis._unexplained import evaluate_with, knots_for

    ratios = []
    generating = dict(effects)
    swap = None
    if alternative is not None:  # the effect is generated as the alternative only
        swap = Alternative({name: generating.pop(name)}, alternative)
        unresolved = {k: v for k, v in (unresolved or {}).items() if k != name}
    for null_sel in _null_selectors(selector, generating, readouts, crossing_s, seed=seed,
                                    replays=replays, unresolved=unresolved, alternative=swap,
                                    noise=noise):
        fitted = dict(_refine_all(null_sel, null_sel.evaluate(dict(effects))).effects)
        rest = {k: v for k, v in fitted.items() if k != name}
        other = [(w, knots_for(null_sel.runs, w, k)) for w, k in splines]
        base = evaluate_with(null_sel, fitted, other)
        alt = evaluate_with(null_sel, rest,
                            [*other, (variable, knots_for(null_sel.runs, variable, n_knots))])
        ratios.append(base.heldout_rms_dps / alt.heldout_rms_dps)
    return tuple(ratios)
