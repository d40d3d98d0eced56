"""Simulator of the temperature-chamber experiment and of a gyro on a CAN bus."""

from gyrotherm.sim._chamber import ChamberModel, ChamberProfile, SetPoint
from gyrotherm.sim._experiment import (
    PAPER_HEATING_MIN,
    chamber_runs,
    heating_profile,
    run_name,
)
from gyrotherm.sim._gyro import DEFAULT_TRUE_BIAS, BiasTruth, GyroParams, simulate

__all__ = [
    "DEFAULT_TRUE_BIAS",
    "PAPER_HEATING_MIN",
    "BiasTruth",
    "ChamberModel",
    "ChamberProfile",
    "GyroParams",
    "SetPoint",
    "chamber_runs",
    "heating_profile",
    "run_name",
    "simulate",
]
