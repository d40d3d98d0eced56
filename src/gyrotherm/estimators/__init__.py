"""Estimators: the Kalman-filtered temperature / ΔT estimator."""

from gyrotherm.estimators._temperature import (
    EstimateSeries,
    EstimatorConfig,
    TemperatureEstimate,
    TemperatureEstimator,
    estimate_series,
)

__all__ = [
    "EstimateSeries",
    "EstimatorConfig",
    "TemperatureEstimate",
    "TemperatureEstimator",
    "estimate_series",
]
