"""Off-catalogue shapes on top of the independent generator (:mod:`._synth`).

The diagnosis' catalogue (:mod:`._effects`) has one exact form per effect. To
see whether it generalises, these shapes differ from those forms on purpose.
Each is evaluated on the generator's *true* die temperature T_die (°C), true
gradient G (°C) and time since power-on t (s) at the output samples, added to the rate and to
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
* ``periodic_t`` (``amplitude_dps``, ``period_c``, ``phase_rad``): a periodic
  bias in die temperature, bias += A·sin(2π·T_die/P + φ), P = 15–30 °C (the
  runs span 30–55 °C: two or more periods).
* ``saturating_dt`` (``amplitude_dps``, ``scale_c``): bias += A·tanh(G/s),
  s = 1–2 °C, G the generator's true gradient (``true_delta_t_c``: chamber air
  + self-heating − case, °C; ramps give a few °C): linear near 0, flat beyond ±2s.
* ``abs_dt`` (``slope_dps_per_c``): bias += k·|G|, the same sign heating and
  cooling (the catalogue's gradient² is even too, but ∝ G²).
* ``rate_hysteresis`` (``amplitude_dps``, ``width_c``, ``rate_c_per_s``): a stop
  operator whose width grows with the rate of the die temperature,
  h ← clip(h + 2·ΔT_die/w, −1, 1), w = w₀·(1 + |dT_die/dt|/r₀), h(0) = 0,
  dT_die/dt by central differences on the 0.5-s grid; bias += A·h. w₀ = 1–3 °C,
  r₀ = 0.02–0.04 °C/s (ramps 1–3.5 °C/min double or triple the width).

Missing parameters are drawn from ``truth_seed`` (one device per run set).
:func:`variant_runs` returns the runs and what was injected.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError
from gyrotherm.analysis.synth._synth import SynthConfig, SynthTruth, synth_runs
from gyrotherm.codecs import Run

FloatArray = NDArray[np.float64]

SHAPES = ("wide_hysteresis", "two_exp_warmup", "logistic_warmup", "bias_step", "periodic_t",
          "saturating_dt", "abs_dt", "rate_hysteresis")
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
        elif name == "periodic_t":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.02, 0.04)))
            p.setdefault("period_c", float(rng.uniform(15.0, 30.0)))
            p.setdefault("phase_rad", float(rng.uniform(0.0, 2.0 * np.pi)))
        elif name == "saturating_dt":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.04, 0.07)))
            p.setdefault("scale_c", float(rng.uniform(1.0, 2.0)))
        elif name == "abs_dt":
            p.setdefault("slope_dps_per_c", sign() * float(rng.uniform(0.006, 0.012)))
        elif name == "rate_hysteresis":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.03, 0.05)))
            p.setdefault("width_c", float(rng.uniform(1.0, 3.0)))
            p.setdefault("rate_c_per_s", float(rng.uniform(0.02, 0.04)))
        out[name] = p
    return out


def stop_operator(temperature_c: FloatArray, width_c: float | FloatArray) -> FloatArray:
    """h ← clip(h + 2·ΔT/w, −1, 1) from h = 0: a branch switches over ``width_c`` °C
    (one width, or one per sample: the width in force at that step)."""
    widths = np.broadcast_to(np.asarray(width_c, dtype=np.float64), np.shape(temperature_c))
    if np.any(widths <= 0):
        raise ConfigError(f"stop operator: width_c = {np.min(widths)!r} must be > 0")
    h = np.zeros(len(temperature_c))
    state = 0.0
    steps = np.diff(temperature_c, prepend=temperature_c[:1]) * (2.0 / widths)
    for i, d in enumerate(steps.tolist()):
        state = min(1.0, max(-1.0, state + d))
        h[i] = state
    return h


def shape_bias(
    name: str, params: Mapping[str, float], time_s: FloatArray, die_c: FloatArray,
    gradient_c: FloatArray | None = None,
) -> FloatArray:
    """Bias (°/s) of off-catalogue shape ``name`` at times ``time_s``, die temperatures
    and true gradients ``gradient_c`` (needed by ``saturating_dt`` and ``abs_dt``)."""
    t = np.asarray(time_s, dtype=np.float64)
    if name in ("wide_hysteresis", "rate_hysteresis"):
        grid = np.arange(0.0, float(t[-1]) + _STEP_S, _STEP_S)
        die = np.interp(grid, t, die_c)
        width: float | FloatArray = params["width_c"]
        if name == "rate_hysteresis":
            rate = np.abs(np.gradient(die, _STEP_S)) if len(die) > 1 else np.zeros(len(die))
            width = params["width_c"] * (1.0 + rate / params["rate_c_per_s"])
        h = stop_operator(die, width)
        return params["amplitude_dps"] * np.interp(t, grid, h)
    if name == "periodic_t":
        return np.asarray(params["amplitude_dps"] * np.sin(
            2.0 * np.pi * np.asarray(die_c) / params["period_c"] + params["phase_rad"]))
    if name in ("saturating_dt", "abs_dt"):
        if gradient_c is None:
            raise ConfigError(f"shape {name!r} needs the true gradient (gradient_c)")
        g = np.asarray(gradient_c, dtype=np.float64)
        if name == "abs_dt":
            return np.asarray(params["slope_dps_per_c"] * np.abs(g))
        return np.asarray(params["amplitude_dps"] * np.tanh(g / params["scale_c"]))
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
    grad = run.extra["true_delta_t_c"]
    extra = np.zeros(len(run))
    for name, params in shapes.items():
        extra += shape_bias(name, params, run.time_s, die, grad)
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
