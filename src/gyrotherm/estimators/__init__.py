"""Estimators: the Kalman-filtered temperature / ΔT estimator."""

from gyrotherm.estimators._series import EstimateSeries, estimate_series
from gyrotherm.estimators._temperature import (
    EstimatorConfig,
    TemperatureEstimate,
    TemperatureEstimator,
)

__all__ = [
    "EstimateSeries",
    "EstimatorConfig",
    "TemperatureEstimate",
    "TemperatureEstimator",
    "estimate_series",
]
