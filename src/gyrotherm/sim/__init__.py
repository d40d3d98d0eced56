"""Simulator of the temperature-chamber experiment and of a gyro on a CAN bus."""

from gyrotherm.bus import INTERFACES, BusAdapter, FrameSink, FrameSource, open_bus
from gyrotherm.sim._chamber import ChamberModel, ChamberProfile, SetPoint
from gyrotherm.sim._experiment import (
    PAPER_HEATING_MIN,
    chamber_runs,
    heating_profile,
    run_name,
)
from gyrotherm.sim._gyro import DEFAULT_TRUE_BIAS, BiasTruth, GyroParams, simulate
from gyrotherm.sim._socketcand import ClientStats, SocketcandServer
from gyrotherm.sim._stream import (
    DEFAULT_TEMPERATURE_PERIOD_S,
    CandumpSink,
    FlushingSink,
    FrameStream,
    PlayStats,
    StopSignal,
    TeeSink,
    frames_from_candump,
    frames_from_run,
    play,
)

__all__ = [
    "DEFAULT_TEMPERATURE_PERIOD_S",
    "DEFAULT_TRUE_BIAS",
    "INTERFACES",
    "PAPER_HEATING_MIN",
    "BiasTruth",
    "BusAdapter",
    "CandumpSink",
    "ChamberModel",
    "ChamberProfile",
    "ClientStats",
    "FlushingSink",
    "FrameSink",
    "FrameSource",
    "FrameStream",
    "GyroParams",
    "PlayStats",
    "SetPoint",
    "SocketcandServer",
    "StopSignal",
    "TeeSink",
    "chamber_runs",
    "frames_from_candump",
    "frames_from_run",
    "heating_profile",
    "open_bus",
    "play",
    "run_name",
    "simulate",
]
