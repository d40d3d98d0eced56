"""gyrotherm: thermal zero-bias compensation for MEMS gyroscopes.

Subpackages follow the data path: ``codecs`` (run files, CAN frames, wire
payloads) → ``estimators`` (temperature / ΔT Kalman filter) → ``compensation``
(bias models, fitting, calibration files) → ``daemon`` → Zenoh → ``client``;
``bus`` opens CAN buses for the daemon and the simulator alike; ``sim``
simulates the temperature-chamber experiment; ``analysis`` diagnoses what a
model misses on measured data.
"""

from gyrotherm._errors import (
    BusError,
    CalibrationError,
    ConfigError,
    DecodeError,
    GyrothermError,
    PublishError,
    RunFileError,
)

__version__ = "0.1.0"

__all__ = [
    "BusError",
    "CalibrationError",
    "ConfigError",
    "DecodeError",
    "GyrothermError",
    "PublishError",
    "RunFileError",
    "__version__",
]
