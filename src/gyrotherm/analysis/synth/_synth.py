"""An independent run generator for testing the diagnosis (NOT gyrotherm's simulator).

The diagnosis must find effects in data that does not come from the physics
it models, so this generator differs from :mod:`gyrotherm.sim` on purpose:

* thermal: a two-node network, chamber air → case → die. The case (where the
  temperature sensor sits, and where the ASIC's self-heating enters) couples
  to the air with ``case_tau_s`` and to the die with ``die_tau_s``; the die
  heat capacity is ``die_capacity_ratio`` of the case's, so the die also
  loads the case. Integrated with explicit Euler on a 0.05 s grid and
  interpolated to the output times. Self-heating switches on at power-on.
* sensor: case temperature + white noise, quantised to ``readout_lsb_c``
  (0.125 °C) and refreshed every ``readout_period_s`` (1.28 s), held between.
* chamber: piecewise-linear set-points (heating and cooling at different
  rates), a controller overshoot at the end of each ramp, Ornstein–Uhlenbeck
  air noise; the logged ``chamber_c`` is the air plus its own thermometer noise.
* bias, seen by the die: ``a0 + a1·u² + a2·u + a3·G + a4·u·G`` with
  u = T_die − 25 °C and G = T_air + P − T_case, the heat-flux gradient across
  the package (P = self-heating, °C; the definition the estimator measures).
* noise: white (ARW), Gauss–Markov bias instability, rate random walk, a
  per-run switch-on offset, output quantisation.

Injected effects (``effects`` maps name → parameters; missing parameters are drawn):

* ``thermal_lag``: ``tau_s`` — the die's coupling time constant to the case
  (otherwise a few seconds): the bias sees a temperature lagging the sensor.
* ``hysteresis``: ``amplitude_dps`` — a play operator of width 0.3–1 °C on the
  die temperature gives the direction (0 before the first move), smoothed by
  a 30–120 s first-order lag; bias += amplitude · state.
* ``warmup``: ``amplitude_dps``, ``tau_s`` — bias += A·exp(−t/τ).
* ``cubic``: ``coefficient_dps_per_c3`` — bias += c·u³.
* ``gradient_quadratic``: ``coefficient_dps_per_c2`` — bias += c·G².
* ``drift``: ``slope_dps_per_h`` — bias += s·t/3600.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run

FloatArray = NDArray[np.float64]

SYNTH_EFFECTS = ("thermal_lag", "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift")
_GRID_S = 0.05


@dataclass(frozen=True)
class SynthConfig:
    """Settings of the independent generator; ``None`` fields are drawn per run set."""

    rate_hz: float = 10.0
    duration_s: float = 7200.0
    readout_lsb_c: float = 0.125
    readout_period_s: float = 1.28
    readout_noise_c: float = 0.02
    case_tau_s: float | None = None
    die_tau_s: float | None = None
    die_capacity_ratio: float = 0.15
    self_heating_c: float | None = None
    arw_deg_per_rth: float | None = None
    bias_instability_deg_per_h: float | None = None
    bi_tau_s: float | None = None
    rrw_deg_per_h_per_rth: float = 1.0
    switch_on_std_dps: float = 0.02
    rate_lsb_dps: float = 0.001
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = set(self.effects) - set(SYNTH_EFFECTS)
        if unknown:
            raise ConfigError(f"synth: unknown effects {sorted(unknown)}; known {SYNTH_EFFECTS}")
        if not 0.1 <= self.rate_hz <= 10_000:
            raise ConfigError(f"synth: rate_hz = {self.rate_hz!r} outside [0.1, 10000] Hz")
        if self.duration_s < 600:
            raise ConfigError(f"synth: duration_s = {self.duration_s!r} is below 600 s")


@dataclass(frozen=True)
class SynthTruth:
    """What was injected (after drawing), for tests to compare against."""

    effects: Mapping[str, Mapping[str, float]]
    coefficients: Mapping[str, float]
    case_tau_s: float
    die_tau_s: float


def _draw_effects(cfg: SynthConfig, rng: np.random.Generator) -> dict[str, dict[str, float]]:
    def sign() -> float:
        return float(rng.choice([-1.0, 1.0]))

    drawn: dict[str, dict[str, float]] = {}
    for name, given in cfg.effects.items():
        p = dict(given)
        if name == "thermal_lag":
            p.setdefault("tau_s", float(rng.uniform(150, 500)))
        elif name == "hysteresis":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.02, 0.05)))
        elif name == "warmup":
            p.setdefault("amplitude_dps", sign() * float(rng.uniform(0.05, 0.12)))
            p.setdefault("tau_s", float(rng.uniform(200, 900)))
        elif name == "cubic":
            p.setdefault("coefficient_dps_per_c3", sign() * float(rng.uniform(4e-6, 8e-6)))
        elif name == "gradient_quadratic":
            p.setdefault("coefficient_dps_per_c2", sign() * float(rng.uniform(1.5e-3, 3e-3)))
        elif name == "drift":
            p.setdefault("slope_dps_per_h", sign() * float(rng.uniform(0.03, 0.06)))
        drawn[name] = p
    return drawn


def _profile(rng: np.random.Generator, duration_s: float) -> tuple[FloatArray, FloatArray]:
    """Set-points: hold, heat, hold, cool (slower), hold, heat back, hold to the end.

    Spans shrink and rates grow for runs shorter than 2 h; if the ramps and
    holds still do not fit in ``duration_s`` − 5 min, the schedule is compressed.
    """
    short = min(1.0, duration_s / 7200.0)
    t0 = float(rng.uniform(15, 30))
    hot = t0 + float(rng.uniform(20, 30)) * short**0.5
    cold = t0 - float(rng.uniform(10, 20)) * short**0.5
    heat = float(rng.uniform(2.0, 3.5)) / 60.0 / short**0.5  # °C/s
    cool = float(rng.uniform(1.0, 2.0)) / 60.0 / short**0.5
    holds = rng.uniform(0.06, 0.10, size=3) * duration_s
    times = [0.0, holds[0]]
    temps = [t0, t0]
    for target, rate, hold in ((hot, heat, holds[1]), (cold, cool, holds[2])):
        times.append(times[-1] + abs(target - temps[-1]) / rate)
        temps.append(target)
        times.append(times[-1] + hold)
        temps.append(target)
    back = t0 + float(rng.uniform(-3, 3))
    times.append(times[-1] + abs(back - cold) / heat)
    temps.append(back)
    squeeze = min(1.0, (duration_s - 300.0) / times[-1])
    times = [x * squeeze for x in times]
    times.append(duration_s + 1.0)
    temps.append(back)
    return np.array(times), np.array(temps)


def _ou(n: int, dt: float, sigma: float, tau_s: float, rng: np.random.Generator) -> FloatArray:
    a = np.exp(-dt / tau_s)
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - a * a)
    y, _ = lfilter([1.0], [1.0, -a], w, zi=[a * rng.standard_normal() * sigma])
    return np.asarray(y, dtype=np.float64)


def _thermal(
    drive_c: FloatArray, case_tau: float, die_tau: float, ratio: float
) -> tuple[FloatArray, FloatArray]:
    """Explicit Euler on the grid: case and die temperatures, °C, driven by air + P."""
    n = len(drive_c)
    case = np.empty(n)
    die = np.empty(n)
    c = d = float(drive_c[0])
    h = _GRID_S
    drive = drive_c.tolist()
    for i in range(n):  # ~150k steps per 2 h: plain Python is fast enough here
        case[i] = c
        die[i] = d
        flow = (d - c) / die_tau
        c += h * ((drive[i] - c) / case_tau + ratio * flow)
        d -= h * flow
    return case, die


def _play(temperature_c: FloatArray, width_c: float) -> FloatArray:
    """Direction of the last move beyond ``width_c`` (0 before the first)."""
    out = np.zeros_like(temperature_c)
    state = 0.0
    lo = hi = float(temperature_c[0])
    for i, v in enumerate(temperature_c.tolist()):
        hi, lo = max(hi, v), min(lo, v)
        if state >= 0 and hi - v > width_c:
            state, lo = -1.0, v
        elif state <= 0 and v - lo > width_c:
            state, hi = 1.0, v
        out[i] = state
    return out


def row_times(rate_hz: float, duration_s: float, rng: np.random.Generator) -> FloatArray:
    """Row stamps at ``rate_hz`` over ``duration_s`` (both ends), each jittered by up to
    ±2 % of a row interval (the first is 0)."""
    n = int(np.floor(duration_s * rate_hz)) + 1
    jitter = rng.uniform(-0.02, 0.02, n) / rate_hz
    t = np.arange(n) / rate_hz + jitter
    t[0] = 0.0
    return t


def read_temperature(time_s: FloatArray, temperature_c: FloatArray, *, period_s: float,
                     lsb_c: float, noise_c: float, rng: np.random.Generator) -> FloatArray:
    """The temperature sensor's readout at the row times ``time_s`` of a true
    temperature (one value per row): a fresh reading at the first row of each refresh
    slot floor(t / ``period_s``) (a slot without a row is never seen), the truth at that
    row plus white noise σ = ``noise_c`` (one draw per fresh reading), rounded to
    ``lsb_c`` (0: not rounded) and held until the next fresh reading. These three
    parameters are the truth :func:`gyrotherm.analysis._prep.characterise` is tested
    against (tests/analysis/test_readout_table.py)."""
    slot = np.floor(time_s / period_s).astype(np.int64)
    fresh = np.r_[True, slot[1:] != slot[:-1]]
    values = temperature_c[fresh] + rng.standard_normal(int(fresh.sum())) * noise_c
    if lsb_c > 0:
        values = np.round(values / lsb_c) * lsb_c
    return np.asarray(values[np.cumsum(fresh) - 1], dtype=np.float64)


def synth_run(cfg: SynthConfig, *, seed: int, name: str = "", truth_seed: int = 0) -> tuple[
    Run, SynthTruth
]:
    """One run; ``truth_seed`` fixes the device (coefficients, effects) shared by a run set."""
    dev = np.random.default_rng(truth_seed)
    rng = np.random.default_rng(seed)
    effects = _draw_effects(cfg, np.random.default_rng(truth_seed + 7919))
    case_tau = cfg.case_tau_s or float(dev.uniform(80, 250))
    die_tau = float(effects["thermal_lag"]["tau_s"]) if "thermal_lag" in effects else (
        cfg.die_tau_s or float(dev.uniform(2, 8)))
    coeffs = {
        "a0": float(dev.normal(0, 0.2)),
        "a1": float(dev.choice([-1, 1]) * dev.uniform(2e-5, 1e-4)),
        "a2": float(dev.choice([-1, 1]) * dev.uniform(0.008, 0.02)),
        "a3": float(dev.choice([-1, 1]) * dev.uniform(0.005, 0.02)),
        "a4": float(dev.choice([-1, 1]) * dev.uniform(0, 3e-4)),
    }
    self_heating = cfg.self_heating_c if cfg.self_heating_c is not None else float(
        dev.uniform(0.5, 2.5))
    arw = cfg.arw_deg_per_rth or float(dev.uniform(0.15, 0.4))
    bi = cfg.bias_instability_deg_per_h or float(dev.uniform(3, 10))
    bi_tau = cfg.bi_tau_s or float(dev.uniform(50, 400))

    times, temps = _profile(rng, cfg.duration_s)
    grid = np.arange(0.0, cfg.duration_s + _GRID_S, _GRID_S)
    setpoint = np.interp(grid, times, temps)
    # controller: first-order response with an overshoot that decays after each ramp
    a = np.exp(-_GRID_S / 40.0)
    lagged, _ = lfilter([1 - a], [1, -a], setpoint, zi=[a * setpoint[0]])
    air = setpoint + 0.3 * (setpoint - np.asarray(lagged))
    air += _ou(len(grid), _GRID_S, float(rng.uniform(0.05, 0.15)), float(rng.uniform(10, 40)), rng)
    power = self_heating * (1.0 - np.exp(-grid / float(dev.uniform(60, 300))))
    case, die = _thermal(air + power, case_tau, die_tau, cfg.die_capacity_ratio)
    grad = air + power - case
    u = die - 25.0
    bias = coeffs["a0"] + coeffs["a1"] * u**2 + coeffs["a2"] * u + coeffs["a3"] * grad \
        + coeffs["a4"] * u * grad
    if "hysteresis" in effects:
        width = float(dev.uniform(0.3, 1.0))
        state = _play(die, width)
        k = np.exp(-_GRID_S / float(dev.uniform(30, 120)))
        smooth, _ = lfilter([1 - k], [1, -k], state, zi=[0.0])
        bias += effects["hysteresis"]["amplitude_dps"] * np.asarray(smooth)
    if "warmup" in effects:
        w = effects["warmup"]
        bias += w["amplitude_dps"] * np.exp(-grid / w["tau_s"])
    if "cubic" in effects:
        bias += effects["cubic"]["coefficient_dps_per_c3"] * u**3
    if "gradient_quadratic" in effects:
        bias += effects["gradient_quadratic"]["coefficient_dps_per_c2"] * grad**2
    if "drift" in effects:
        bias += effects["drift"]["slope_dps_per_h"] * grid / 3600.0

    t = row_times(cfg.rate_hz, cfg.duration_s, rng)
    n = len(t)
    reading = read_temperature(t, np.interp(t, grid, case), period_s=cfg.readout_period_s,
                               lsb_c=cfg.readout_lsb_c, noise_c=cfg.readout_noise_c, rng=rng)

    dt = 1.0 / cfg.rate_hz
    true_bias = np.interp(t, grid, bias)
    white = rng.standard_normal(n) * arw / 60.0 * np.sqrt(cfg.rate_hz)
    gm = _ou(n, dt, bi / 3600.0 / 0.62, bi_tau, rng)
    rrw = np.cumsum(rng.standard_normal(n)) * cfg.rrw_deg_per_h_per_rth / 3600 / 60 * np.sqrt(dt)
    offset = float(rng.normal(0, cfg.switch_on_std_dps))
    rate = true_bias + white + gm + rrw + offset
    if cfg.rate_lsb_dps > 0:
        rate = np.round(rate / cfg.rate_lsb_dps) * cfg.rate_lsb_dps
    chamber = np.interp(t, grid, air) + rng.standard_normal(n) * 0.02
    run = Run(
        name=name or f"synth-{seed}",
        time_s=t,
        temperature_c=reading,
        rates_dps={"x": rate},
        chamber_c=chamber,
        true_bias_dps={"x": true_bias},
        metadata={"generator": "gyrotherm.analysis.synth._synth", "seed": str(seed),
                  "switch_on_offset_dps": repr(offset)},
        extra={"true_temperature_c": np.interp(t, grid, die),
               "true_delta_t_c": np.interp(t, grid, grad)},
    )
    truth = SynthTruth(effects=effects, coefficients=coeffs, case_tau_s=case_tau,
                       die_tau_s=die_tau)
    return run, truth


def synth_runs(cfg: SynthConfig, *, n_runs: int = 5, seed: int = 0) -> tuple[
    list[Run], SynthTruth
]:
    """``n_runs`` runs of one device (shared coefficients and effects), seeds from ``seed``."""
    if n_runs < 1:
        raise ConfigError(f"synth: n_runs = {n_runs!r} must be ≥ 1")
    out = []
    truth: SynthTruth | None = None
    for i in range(n_runs):
        run, truth = synth_run(cfg, seed=seed * 1000 + i + 1, name=f"synth-{seed}-{i}",
                               truth_seed=seed)
        out.append(run)
    assert truth is not None
    return out, truth
