"""A simulated static MEMS gyro in a chamber: thermal, sensor, bias and noise physics.

Thermal: first-order coupling of the die to the chamber air plus self-heating,
``τ·dT/dt = T_air + P − T`` (τ = ``tau_s``, P = ``self_heating_c``), integrated
exactly per sample. The gradient the bias sees is the heat-flux gradient
``ΔT = T_air + P − T = τ·dT/dt`` — what the estimator measures.

Temperature sensor: true T plus white noise, quantised, refreshed every
``temperature_period_s`` and held in between.

Rate output (per axis, °/s), after IEEE Std 952-1997 (Allan variance terms):

* bias(T, ΔT) from a configurable model with physical coefficients;
* angle random walk N (°/√h): white noise of std N/60·√f_s per sample;
* bias instability B (°/h): Gauss–Markov process of correlation time
  ``bi_tau_s`` and std B/0.62, whose Allan deviation peaks near B;
* rate random walk K (°/h/√h): random walk with increments K/3600/60·√dt;
* a per-run switch-on offset ~ N(0, ``switch_on_std_dps``) (repeatability);
* output quantisation to ``rate_lsb_dps``.

Optional, off by default (calibrated profiles, :mod:`._profiles`): a white-noise
level per axis (``arw_by_axis_deg_per_rth`` overrides N on the axes it names),
narrow spectral lines (``lines``, :mod:`._lines`), and a per-run ΔT sensitivity:
the true dT coefficient plus δ ~ N(0, ``dt_run_std_dps_per_c``) drawn per run and
axis, bias += δ·ΔT (the coupling of the gradient to the bias changing from run to
run, e.g. with mounting or the chamber's air flow; Tang et al. §5).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run
from gyrotherm.codecs._runfile import TEMPERATURE_PERIOD_KEY
from gyrotherm.compensation import ModelSpec, Term, get_model
from gyrotherm.sim._chamber import ChamberModel, ChamberProfile, first_order, ou_process
from gyrotherm.sim._lines import SpectralLine, line_signal_dps

FloatArray = NDArray[np.float64]

#: Default true bias, °/s, per axis: paper model in physical units (T, ΔT in °C).
DEFAULT_TRUE_BIAS: Mapping[str, Mapping[str, float]] = {
    "x": {"T^2": 1.2e-4, "T": -0.010, "dT": 0.050, "T*dT": -4.0e-4, "1": 0.30},
    "y": {"T^2": -8.0e-5, "T": 0.006, "dT": 0.035, "T*dT": 3.0e-4, "1": -0.20},
    "z": {"T^2": 5.0e-5, "T": -0.004, "dT": -0.030, "T*dT": 2.0e-4, "1": 0.10},
}


@dataclass(frozen=True)
class BiasTruth:
    """The simulator's true bias: a model and its physical coefficients per axis."""

    model: ModelSpec = field(default_factory=lambda: get_model("paper"))
    coefficients: Mapping[str, Mapping[str, float]] = field(
        default_factory=lambda: DEFAULT_TRUE_BIAS
    )

    def __post_init__(self) -> None:
        names = set(self.model.term_names)
        for axis, coeffs in self.coefficients.items():
            extra = set(coeffs) - names
            if extra:
                raise ConfigError(
                    f"true bias, axis {axis}: terms {sorted(extra)} not in model "
                    f"{self.model.name!r} {sorted(names)}"
                )

    def bias_dps(self, axis: str, temperature_c: FloatArray, delta_t_c: FloatArray) -> FloatArray:
        out = np.zeros_like(temperature_c)
        for name, c in self.coefficients[axis].items():
            t = Term.parse(name)
            out += c * temperature_c**t.t_power * delta_t_c**t.dt_power
        return out


@dataclass(frozen=True)
class GyroParams:
    """Physical parameters of the simulated gyro (units in the names)."""

    tau_s: float = 120.0
    self_heating_c: float = 0.0
    temperature_noise_c: float = 0.02
    temperature_lsb_c: float = 0.01
    temperature_period_s: float = 0.1
    arw_deg_per_rth: float = 0.9
    bias_instability_deg_per_h: float = 20.0
    bi_tau_s: float = 100.0
    rrw_deg_per_h_per_rth: float = 5.0
    switch_on_std_dps: float = 0.01
    rate_lsb_dps: float = 0.002
    axes: tuple[str, ...] = ("x", "y", "z")
    bias: BiasTruth = field(default_factory=BiasTruth)
    arw_by_axis_deg_per_rth: Mapping[str, float] = field(default_factory=dict)
    lines: tuple[SpectralLine, ...] = ()
    dt_run_std_dps_per_c: float = 0.0

    def arw_for(self, axis: str) -> float:
        """The white-noise level N (°/√h) of ``axis``."""
        return self.arw_by_axis_deg_per_rth.get(axis, self.arw_deg_per_rth)

    def __post_init__(self) -> None:
        for name in ("tau_s", "temperature_period_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"gyro.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("temperature_noise_c", "temperature_lsb_c", "arw_deg_per_rth",
                     "bias_instability_deg_per_h", "rrw_deg_per_h_per_rth",
                     "switch_on_std_dps", "rate_lsb_dps", "dt_run_std_dps_per_c"):
            if getattr(self, name) < 0:
                raise ConfigError(f"gyro.{name} must be ≥ 0, got {getattr(self, name)!r}")
        for axis, arw in self.arw_by_axis_deg_per_rth.items():
            if not arw >= 0:
                raise ConfigError(f"gyro.arw_by_axis_deg_per_rth[{axis!r}] must be ≥ 0, "
                                  f"got {arw!r}")
        missing = set(self.axes) - set(self.bias.coefficients)
        if missing:
            raise ConfigError(f"gyro: no true bias for axes {sorted(missing)}")

    def quiet(self) -> GyroParams:
        """The same gyro with every noise source, offset and quantisation off."""
        from dataclasses import replace

        return replace(self, temperature_noise_c=0.0, temperature_lsb_c=0.0,
                       arw_deg_per_rth=0.0, bias_instability_deg_per_h=0.0,
                       rrw_deg_per_h_per_rth=0.0, switch_on_std_dps=0.0, rate_lsb_dps=0.0,
                       arw_by_axis_deg_per_rth={}, lines=(), dt_run_std_dps_per_c=0.0)


def _quantise(x: FloatArray, lsb: float) -> FloatArray:
    return np.round(x / lsb) * lsb if lsb > 0 else x


def simulate(
    profile: ChamberProfile,
    *,
    name: str,
    gyro: GyroParams | None = None,
    chamber: ChamberModel | None = None,
    rate_hz: float = 10.0,
    seed: int = 0,
    metadata: Mapping[str, str] | None = None,
) -> Run:
    """Simulate a static gyro through ``profile``; returns a run with truth columns."""
    gyro = gyro or GyroParams()
    chamber = chamber or ChamberModel()
    if not 0.01 <= rate_hz <= 10_000:
        raise ConfigError(f"rate_hz = {rate_hz!r} is outside [0.01, 10000] Hz")
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n = int(np.floor(profile.duration_s * rate_hz)) + 1
    t = np.arange(n, dtype=np.float64) * dt
    air = profile.realise(t, chamber, rng)
    drive = air + gyro.self_heating_c
    die = first_order(drive, dt, gyro.tau_s, float(air[0]))
    grad = drive - die  # = τ·dT/dt
    # temperature sensor: sampled every period, held in between
    k = np.floor(t / gyro.temperature_period_s + 1e-9).astype(np.int64)
    first = np.r_[True, k[1:] != k[:-1]]
    fresh = die[first] + rng.standard_normal(int(first.sum())) * gyro.temperature_noise_c
    reading = _quantise(fresh, gyro.temperature_lsb_c)[np.cumsum(first) - 1]

    rates: dict[str, FloatArray] = {}
    truth: dict[str, FloatArray] = {}
    for axis in gyro.axes:
        bias = gyro.bias.bias_dps(axis, die, grad)
        white = rng.standard_normal(n) * gyro.arw_for(axis) / 60.0 * np.sqrt(rate_hz)
        bi = (ou_process(n, dt, gyro.bias_instability_deg_per_h / 3600.0 / 0.62,
                         gyro.bi_tau_s, rng) if gyro.bias_instability_deg_per_h > 0 else 0.0)
        rrw_step = gyro.rrw_deg_per_h_per_rth / 3600 / 60 * np.sqrt(dt)
        rrw = np.cumsum(rng.standard_normal(n)) * rrw_step
        offset = rng.standard_normal() * gyro.switch_on_std_dps
        if gyro.dt_run_std_dps_per_c > 0:  # drawn only when on: default streams unchanged
            bias = bias + rng.standard_normal() * gyro.dt_run_std_dps_per_c * grad
        out = bias + offset + white + bi + rrw
        if gyro.lines:  # drawn last: runs without lines keep their random stream
            out = out + line_signal_dps(gyro.lines, axis, t, rng)
        rates[axis] = _quantise(out, gyro.rate_lsb_dps)
        truth[axis] = bias
    meta = {"seed": str(seed), "rate_hz": f"{rate_hz:g}", "tau_s": f"{gyro.tau_s:g}",
            TEMPERATURE_PERIOD_KEY: repr(float(gyro.temperature_period_s)), **(metadata or {})}
    return Run(name=name, time_s=t, temperature_c=reading, rates_dps=rates,
               chamber_c=air, true_bias_dps=truth, metadata=meta,
               extra={"true_temperature_c": die, "true_delta_t_c": grad})
