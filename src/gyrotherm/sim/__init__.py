"""Simulator of the temperature-chamber experiment and of a gyro on a CAN bus."""

from gyrotherm.sim._bus import INTERFACES, BusAdapter, FrameSink, FrameSource, open_bus
from gyrotherm.sim._chamber import ChamberModel, ChamberProfile, SetPoint
from gyrotherm.sim._experiment import (
    PAPER_HEATING_MIN,
    chamber_runs,
    heating_profile,
    run_name,
)
from gyrotherm.sim._gyro import DEFAULT_TRUE_BIAS, BiasTruth, GyroParams, simulate
from gyrotherm.sim._socketcand import ClientStats, SocketcandServer

__all__ = [
    "DEFAULT_TRUE_BIAS",
    "INTERFACES",
    "PAPER_HEATING_MIN",
    "BiasTruth",
    "BusAdapter",
    "ChamberModel",
    "ChamberProfile",
    "ClientStats",
    "FrameSink",
    "FrameSource",
    "GyroParams",
    "SetPoint",
    "SocketcandServer",
    "chamber_runs",
    "heating_profile",
    "open_bus",
    "run_name",
    "simulate",
]
