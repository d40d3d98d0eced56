"""Calibrating gyrotherm's simulator to measured runs and replaying their temperatures.

Calibration (per axis, from the measured runs):

* ``tau_s`` and ``self_heating_c``: regressed from chamber − T = τ·dT/dt − P
  when the runs log the chamber (else 120 s and 0 °C);
* temperature readout: period, LSB and noise read off the readings;
* ``arw_deg_per_rth`` = σ₁·60/√f_s from the per-sample white noise σ₁
  (first differences / √2); ``rate_lsb_dps``: the output's quantum;
* bias instability: a Gauss–Markov fit to the autocovariance of the baseline's
  1-s residuals (σ, τ) → B = 0.62·σ (°/h), ``bi_tau_s`` = τ;
* ``switch_on_std_dps``: spread of the fitted per-run offsets;
* bias: zero inside :func:`gyrotherm.sim.simulate`; the fitted model (baseline
  or extended) is added afterwards on the simulator's true die temperature
  and gradient (:func:`gyrotherm.analysis._effects.add_bias`).

Replay: each measured run's environment temperature (the logged chamber, or
T + ΔT reconstructed from the readings) becomes a chamber profile with
set-points every 10 s, realised without lag, bow or noise, at the run's
sample rate (capped at 100 Hz: the diagnosis works on 1-s blocks).
:func:`replay_noise` simulates with zero bias, so that one simulation per seed
serves every model (:func:`replay` adds one model's bias to it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._effects import ExtendedModel, add_bias
from gyrotherm.analysis._prep import Prepared, Readout
from gyrotherm.codecs import Run
from gyrotherm.sim import BiasTruth, ChamberModel, ChamberProfile, GyroParams, simulate

MAX_SIM_RATE_HZ = 100.0


@dataclass(frozen=True)
class SimCalibration:
    """The simulator settings fitted to the measured runs."""

    gyro: GyroParams
    tau_from_chamber: bool

    def to_dict(self) -> dict[str, float | bool]:
        g = self.gyro
        return {
            "tau_s": g.tau_s,
            "tau_from_chamber": self.tau_from_chamber,
            "self_heating_c": g.self_heating_c,
            "temperature_noise_c": g.temperature_noise_c,
            "temperature_lsb_c": g.temperature_lsb_c,
            "temperature_period_s": g.temperature_period_s,
            "arw_deg_per_rth": g.arw_deg_per_rth,
            "bias_instability_deg_per_h": g.bias_instability_deg_per_h,
            "bi_tau_s": g.bi_tau_s,
            "switch_on_std_dps": g.switch_on_std_dps,
            "rate_lsb_dps": g.rate_lsb_dps,
        }


def calibrate(
    readouts: Sequence[Readout],
    *,
    axis: str,
    tau_s: float,
    self_heating_c: float,
    tau_from_chamber: bool,
    gm_sigma_dps: float,
    gm_tau_s: float,
    offsets_dps: Sequence[float],
) -> SimCalibration:
    med = {k: float(np.median([getattr(r, k) for r in readouts]))
           for k in ("period_s", "lsb_c", "noise_c", "rate_lsb_dps", "sample_noise_dps")}
    arw = float(np.median([r.sample_noise_dps * 60.0 / math.sqrt(r.sample_rate_hz)
                           for r in readouts]))
    gyro = GyroParams(
        tau_s=tau_s,
        self_heating_c=self_heating_c,
        temperature_noise_c=max(med["noise_c"] - med["lsb_c"] / math.sqrt(6), 0.0)
        if med["lsb_c"] > 0 else med["noise_c"],
        temperature_lsb_c=med["lsb_c"],
        temperature_period_s=med["period_s"],
        arw_deg_per_rth=arw,
        bias_instability_deg_per_h=0.62 * gm_sigma_dps * 3600.0,
        bi_tau_s=gm_tau_s,
        rrw_deg_per_h_per_rth=0.0,
        switch_on_std_dps=float(np.std(offsets_dps, ddof=1)) if len(offsets_dps) > 1 else 0.0,
        rate_lsb_dps=med["rate_lsb_dps"],
        axes=(axis,),
        bias=BiasTruth(coefficients={axis: {}}),
    )
    return SimCalibration(gyro, tau_from_chamber)


@dataclass(frozen=True)
class _ReplayProfile(ChamberProfile):
    """A profile whose air follows its set-points exactly under a quiet chamber.

    With ``ChamberModel(lag_s=0, bow_c=0, noise_c=0)``,
    :meth:`ChamberProfile.realise` returns the linear interpolation of the
    set-points and draws nothing from ``rng``; it gets there through a
    bow loop over every ramp (zero here) that costs set-points × samples —
    half of a replay's time. This returns the same array directly.
    """

    def realise(
        self, time_s: NDArray[np.float64], model: ChamberModel, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        if model.lag_s > 0 or model.bow_c != 0 or model.noise_c > 0:
            return super().realise(time_s, model, rng)
        return self.setpoint_c(time_s)


def environment_c(p: Prepared) -> np.ndarray:
    """The environment temperature a run saw: the chamber log, else T + ΔT."""
    if p.chamber_c is not None:
        return p.chamber_c
    return p.temperature_c + p.delta_t_c


def replay_noise(
    runs: Sequence[Run],
    prepared: Sequence[Prepared],
    calibration: SimCalibration,
    *,
    axis: str,
    seed: int = 0,
) -> list[Run]:
    """Simulate every run's temperature history with zero bias (noise, offsets and
    quantisation only); run i uses seed ``seed·1000 + i``. Add a model's bias with
    :func:`gyrotherm.analysis._effects.add_bias`."""
    out = []
    quiet_chamber = ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0)
    for i, (run, p) in enumerate(zip(runs, prepared, strict=True)):
        env = environment_c(p)
        t = p.time_s - p.time_s[0]
        pick = np.r_[np.arange(0, len(t), 10), len(t) - 1]
        pick = np.unique(pick)
        times = t[pick]
        times[0] = 0.0
        keep = np.r_[True, np.diff(times) > 0]
        temps = np.clip(env[pick][keep], -100.0, 200.0)
        profile = _ReplayProfile.from_pairs(list(zip(times[keep].tolist(), temps.tolist(),
                                                     strict=True)))
        rate = min(1.0 / float(np.median(np.diff(run.time_s))), MAX_SIM_RATE_HZ)
        out.append(simulate(profile, name=f"sim-{run.name}", gyro=calibration.gyro,
                            chamber=quiet_chamber, rate_hz=rate, seed=seed * 1000 + i,
                            metadata={"replay_of": run.name}))
    return out


def replay(
    runs: Sequence[Run],
    prepared: Sequence[Prepared],
    calibration: SimCalibration,
    model: ExtendedModel,
    *,
    axis: str,
    seed: int = 0,
) -> list[Run]:
    """Simulate every run's temperature history with ``model`` as the bias."""
    return [add_bias(sim, model, axis)
            for sim in replay_noise(runs, prepared, calibration, axis=axis, seed=seed)]
