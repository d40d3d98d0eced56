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

__all__ = [
    "CanConfig",
    "Counters",
    "Daemon",
    "DaemonConfig",
    "Notifier",
    "Pipeline",
    "RunSummary",
    "Sink",
    "ZenohConfig",
    "load_config",
    "parse_config",
]
