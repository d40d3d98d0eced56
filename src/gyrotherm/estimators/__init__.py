"""Estimators: the Kalman-filtered temperature / ΔT estimator."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gyrotherm._lazy import lazy_names
from gyrotherm.estimators._temperature import (
    EstimatorConfig,
    TemperatureEstimate,
    TemperatureEstimator,
)

if TYPE_CHECKING:  # offline (a recorded series): lazy, see _LAZY
    from gyrotherm.estimators._series import EstimateSeries, estimate_series

_LAZY = {
    "EstimateSeries": "gyrotherm.estimators._series",
    "estimate_series": "gyrotherm.estimators._series",
}

__all__ = [
    "EstimateSeries",
    "EstimatorConfig",
    "TemperatureEstimate",
    "TemperatureEstimator",
    "estimate_series",
]


# the offline names, imported on first use (PEP 562): the daemon never loads them
__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
