"""The estimator a calibration is fitted with, chosen from the runs' temperature readout:
one rule for ``gyrotherm fit`` and ``gyrotherm diagnose --calibration``.

Per run (:func:`run_readout`, cheap enough for the workers that read the logs): the
readout's refresh period, LSB and noise (:func:`~._prep.characterise`), and, when the run
logs the chamber temperature, its smoothed 1-s block features, from which τ is
regressed over all runs (:func:`~._prep.fit_tau`: chamber − T = τ·dT/dt − P) exactly as
the diagnosis does. :func:`estimator_of` then gives the settings
(:func:`~._prep.estimator_for`: every new reading fed, noise from the readout,
q = 1e-7 °C²/s³; chosen by held-out deployed error, docs/findings.md §6) with that τ, or
120 s without a chamber column (the paper model is linear in ΔT: τ only rescales the ΔT
coefficients).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from gyrotherm._errors import CalibrationError
from gyrotherm.analysis._prep import (
    DEFAULT_TAU_S,
    Prepared,
    Readout,
    characterise,
    estimator_for,
    fit_tau,
    prepare,
)
from gyrotherm.codecs import Run
from gyrotherm.estimators import EstimatorConfig


@dataclass(frozen=True)
class RunReadout:
    """One run's readout and, when it logs the chamber, its features for the τ fit."""

    name: str
    readout: Readout
    tau_blocks: Prepared | None
    imu: tuple[str, str, str] = ("", "", "")
    """The run's ``(vehicle_id, device_id, sensor_id)`` ("" when absent): ``fleet`` chooses
    each IMU's estimator from its own runs."""

    @property
    def device(self) -> str:
        """The run's ``device_id`` ("" when absent): ``fit`` chooses each device's
        calibration's estimator from its own runs."""
        return self.imu[1]


@dataclass(frozen=True)
class ChosenEstimator:
    """:func:`estimator_of`'s result: the settings and where they came from."""

    estimator: EstimatorConfig
    tau_from_chamber: bool
    runs: int

    def describe(self) -> str:
        """One line for the user: what was measured and what it set."""
        e = self.estimator
        if not self.runs:
            return "estimator: the defaults (no run long enough to characterise its readout)"
        tau = (f"τ {e.tau_s:.4g} s regressed on the chamber temperature" if self.tau_from_chamber
               else f"τ {e.tau_s:g} s (no chamber_c column: the default)")
        return (f"estimator from the temperature readout of {self.runs} run(s): refresh "
                f"{e.update_period_s:.4g} s, LSB {e.quantisation_c:.4g} °C, noise "
                f"{e.noise_c:.4g} °C, q {e.process_noise_c2_per_s3:g} °C²/s³; {tau}")

    def to_dict(self) -> dict[str, object]:
        return {"rule": "readout characterised (gyrotherm.analysis._readout_estimator)",
                "tau_from_chamber": self.tau_from_chamber, "runs": self.runs}


def run_readout(run: Run, axis: str | None = None) -> RunReadout | None:
    """:class:`RunReadout` of ``run`` (``axis``: the rate axis characterised beside the
    temperature; default the run's first); None for a run too short to characterise
    (< 10 rows: the command that reads it says what else is wrong with it)."""
    axis = axis or next(iter(run.rates_dps))
    try:
        readout = characterise(run, axis)
    except CalibrationError:
        return None
    blocks = (prepare(run, axis, EstimatorConfig(tau_s=DEFAULT_TAU_S))
              if run.chamber_c is not None else None)
    vehicle, device, sensor = (str(run.metadata.get(k, "") or "")
                               for k in ("vehicle_id", "device_id", "sensor_id"))  # an IMU
    return RunReadout(run.name, readout, blocks, (vehicle, device, sensor))


def estimator_of(readouts: Sequence[RunReadout]) -> ChosenEstimator:
    """The estimator for a calibration of these runs (module docstring); the defaults
    when there is none (every run too short to characterise)."""
    if not readouts:
        return ChosenEstimator(EstimatorConfig(), False, 0)
    est = estimator_for([r.readout for r in readouts])
    blocks = [r.tau_blocks for r in readouts if r.tau_blocks is not None]
    tau = fit_tau(blocks) if blocks else None  # the runs that log it, as diagnose does
    return ChosenEstimator(replace(est, tau_s=tau[0] if tau else DEFAULT_TAU_S),
                           tau is not None, len(readouts))

