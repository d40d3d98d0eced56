"""Estimators: the Kalman-filtered temperature / ΔT estimator."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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


def __getattr__(name: str) -> Any:
    """The offline names, imported on first use (PEP 562): the daemon never loads them."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
