"""Off-catalogue shapes on top of the independent generator (:mod:`._synth`).

The diagnosis' catalogue (:mod:`._effects`) has one exact form per effect. To
see whether it generalises, these shapes differ from those forms on purpose.
Each is evaluated on the generator's *true* die temperature T_die (°C) and
time since power-on t (s) at the output samples, added to the rate and to
``true_bias_dps``, and the rate is re-quantised to the generator's LSB:

* ``wide_hysteresis`` (``amplitude_dps``, ``width_c``): a stop operator,
  h ← clip(h + 2·ΔT_die/w, −1, 1), h(0) = 0; bias += A·h. A branch takes
  w (3–6 °C) of travel to switch, linearly; no dead band, no exponential
  saturation (the catalogue's play operator of width w with exponential
  saturation is a different curve).
* ``two_exp_warmup`` (``amplitude_1_dps``, ``tau_1_s``, ``amplitude_2_dps``,
  ``tau_2_s``): bias += A₁·exp(−t/τ₁) + A₂·exp(−t/τ₂), τ₂ ≈ 5–8 τ₁.
* ``logistic_warmup`` (``amplitude_dps``, ``t_half_s``, ``width_s``):
  bias += A / (1 + exp((t − t½)/s)): flat, then a decay centred on t½.
* ``bias_step`` (``amplitude_dps``, ``at_c``, ``width_c``): a smooth bias step
  in temperature, bias += A·½·(1 + tanh((T_die − T₀)/w)), T₀ = 30 °C by
  default (every generated run crosses it: holds at 15–30 °C, heats to
  ≥ 35 °C, cools to ≤ 20 °C). No catalogued effect has this form.

Missing parameters are drawn from ``truth_seed`` (one device per run set).
:func:`variant_runs` returns the runs and what was injected.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError
from gyrotherm.analysis._synth import SynthConfig, SynthTruth, synth_runs
from gyrotherm.codecs import Run

FloatArray = NDArray[np.float64]

SHAPES = ("wide_hysteresis", "two_exp_warmup", "logistic_warmup", "bias_step")
_STEP_S = 0.5
"""Grid (s) on which the stop operator runs before interpolation to the samples."""


@dataclass(frozen=True)
class VariantTruth:
    """What was injected: the generator's catalogued effects and the extra shapes."""

    base: SynthTruth
    shapes: Mapping[str, Mapping[str, float]] = field(default_factory=dict)


def _draw(shapes: Mapping[str, Mapping[str, float]], seed: int) -> dict[str, dict[str, float]]:
    rng = np.random.default_rng(seed + 104_729)

    def sign() -> float:
        return float(rng.choice([-1.0, 1.0]))

    out: dict[str, dict[str, float]] = {}
    for name, given in shapes.items():
        p = dict(given)
        if name == "wide_hysteresis":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.03, 0.05)))
            p.setdefault("width_c", float(rng.uniform(3.0, 6.0)))
        elif name == "two_exp_warmup":
            s = sign()
            p.setdefault("amplitude_1_dps", s * float(rng.uniform(0.04, 0.08)))
            p.setdefault("tau_1_s", float(rng.uniform(80.0, 200.0)))
            p.setdefault("amplitude_2_dps", s * float(rng.uniform(0.03, 0.06)))
            p.setdefault("tau_2_s", p["tau_1_s"] * float(rng.uniform(5.0, 8.0)))
        elif name == "logistic_warmup":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.05, 0.1)))
            p.setdefault("t_half_s", float(rng.uniform(400.0, 900.0)))
            p.setdefault("width_s", float(rng.uniform(60.0, 150.0)))
        elif name == "bias_step":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.03, 0.05)))
            p.setdefault("at_c", 30.0)
            p.setdefault("width_c", float(rng.uniform(1.0, 2.0)))
        out[name] = p
    return out


def stop_operator(temperature_c: FloatArray, width_c: float) -> FloatArray:
    """h ← clip(h + 2·ΔT/w, −1, 1) from h = 0: a branch switches over ``width_c`` °C."""
    if width_c <= 0:
        raise ConfigError(f"stop operator: width_c = {width_c!r} must be > 0")
    h = np.zeros(len(temperature_c))
    state = 0.0
    steps = np.diff(temperature_c, prepend=temperature_c[:1]) * (2.0 / width_c)
    for i, d in enumerate(steps.tolist()):
        state = min(1.0, max(-1.0, state + d))
        h[i] = state
    return h


def shape_bias(
    name: str, params: Mapping[str, float], time_s: FloatArray, die_c: FloatArray
) -> FloatArray:
    """Bias (°/s) of off-catalogue shape ``name`` at times ``time_s`` and die temperatures."""
    t = np.asarray(time_s, dtype=np.float64)
    if name == "wide_hysteresis":
        grid = np.arange(0.0, float(t[-1]) + _STEP_S, _STEP_S)
        h = stop_operator(np.interp(grid, t, die_c), params["width_c"])
        return params["amplitude_dps"] * np.interp(t, grid, h)
    if name == "two_exp_warmup":
        return np.asarray(params["amplitude_1_dps"] * np.exp(-t / params["tau_1_s"])
                          + params["amplitude_2_dps"] * np.exp(-t / params["tau_2_s"]))
    if name == "logistic_warmup":
        z = np.clip((t - params["t_half_s"]) / params["width_s"], -50.0, 50.0)
        return np.asarray(params["amplitude_dps"] / (1.0 + np.exp(z)))
    if name == "bias_step":
        return np.asarray(params["amplitude_dps"] * 0.5
                          * (1.0 + np.tanh((die_c - params["at_c"]) / params["width_c"])))
    raise ConfigError(f"unknown off-catalogue shape {name!r}; known: {', '.join(SHAPES)}")


def _with_shapes(run: Run, shapes: Mapping[str, Mapping[str, float]], lsb_dps: float) -> Run:
    die = run.extra["true_temperature_c"]
    extra = np.zeros(len(run))
    for name, params in shapes.items():
        extra += shape_bias(name, params, run.time_s, die)
    rate = run.rates_dps["x"] + extra
    if lsb_dps > 0:
        rate = np.round(rate / lsb_dps) * lsb_dps
    truth = dict(run.true_bias_dps)
    truth["x"] = truth["x"] + extra
    return replace(run, rates_dps={**run.rates_dps, "x": rate}, true_bias_dps=truth)


def variant_runs(
    cfg: SynthConfig,
    *,
    shapes: Mapping[str, Mapping[str, float]] | None = None,
    n_runs: int = 4,
    seed: int = 0,
) -> tuple[list[Run], VariantTruth]:
    """:func:`~._synth.synth_runs` (catalogued effects in ``cfg.effects``) plus the
    off-catalogue ``shapes`` (name → parameters; missing ones drawn from ``seed``)."""
    unknown = set(shapes or {}) - set(SHAPES)
    if unknown:
        raise ConfigError(f"variant: unknown shapes {sorted(unknown)}; known: {', '.join(SHAPES)}")
    runs, base = synth_runs(cfg, n_runs=n_runs, seed=seed)
    drawn = _draw(shapes or {}, seed)
    if drawn:
        runs = [_with_shapes(r, drawn, cfg.rate_lsb_dps) for r in runs]
    return runs, VariantTruth(base=base, shapes=drawn)
