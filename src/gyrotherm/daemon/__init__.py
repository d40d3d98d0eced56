"""The streaming daemon: CAN → T/ΔT estimator → compensator → Zenoh."""

from gyrotherm.daemon._config import (
    CanConfig,
    DaemonConfig,
    ZenohConfig,
    load_config,
    parse_config,
)
from gyrotherm.daemon._pipeline import Counters, Pipeline, Sink
from gyrotherm.daemon._sdnotify import Notifier
from gyrotherm.daemon._service import Daemon, RunSummary
from gyrotherm.daemon._vehicle import (
    ConsistencyConfig,
    VehicleConfig,
    load_vehicle_config,
    parse_vehicle_config,
)

__all__ = [
    "CanConfig",
    "ConsistencyConfig",
    "Counters",
    "Daemon",
    "DaemonConfig",
    "Notifier",
    "Pipeline",
    "RunSummary",
    "Sink",
    "VehicleConfig",
    "ZenohConfig",
    "load_config",
    "load_vehicle_config",
    "parse_config",
    "parse_vehicle_config",
]
