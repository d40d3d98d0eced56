"""Compensation: bias models in T and ΔT, least-squares fitting, calibration files,
the online compensator (base polynomial + effects kernels, one per axis), and the
boot-time zero."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gyrotherm._lazy import lazy_names
from gyrotherm.compensation._calibration import BiasEstimate, Calibration, ValidRange
from gyrotherm.compensation._calibration_file import (
    load_calibration,
    parse_calibration,
    read_calibration,
)
from gyrotherm.compensation._compensator import CompensatedSeries, Compensator
from gyrotherm.compensation._models import MODELS, ModelSpec, Scaling, Term, get_model
from gyrotherm.compensation._zero import BootZero, ZeroConfig, ZeroSeries, ZeroStatus, zero_series

if TYPE_CHECKING:  # offline (fitting, scores): lazy, see _LAZY
    from gyrotherm.compensation._fit import (
        METHODS,
        HeldOut,
        Method,
        RemovedBias,
        RunFeatures,
        default_scaling,
        features,
        fit,
        fit_per_run,
        leave_one_out,
        mean_coefficients,
        removed_bias,
        score,
    )
    from gyrotherm.compensation._metrics import ErrorMetrics, RunScore

_LAZY = {
    "METHODS": "gyrotherm.compensation._fit",
    "HeldOut": "gyrotherm.compensation._fit",
    "Method": "gyrotherm.compensation._fit",
    "RemovedBias": "gyrotherm.compensation._fit",
    "RunFeatures": "gyrotherm.compensation._fit",
    "default_scaling": "gyrotherm.compensation._fit",
    "features": "gyrotherm.compensation._fit",
    "fit": "gyrotherm.compensation._fit",
    "fit_per_run": "gyrotherm.compensation._fit",
    "leave_one_out": "gyrotherm.compensation._fit",
    "mean_coefficients": "gyrotherm.compensation._fit",
    "removed_bias": "gyrotherm.compensation._fit",
    "score": "gyrotherm.compensation._fit",
    "ErrorMetrics": "gyrotherm.compensation._metrics",
    "RunScore": "gyrotherm.compensation._metrics",
}

__all__ = [
    "METHODS",
    "MODELS",
    "BiasEstimate",
    "BootZero",
    "Calibration",
    "CompensatedSeries",
    "Compensator",
    "ErrorMetrics",
    "HeldOut",
    "Method",
    "ModelSpec",
    "RemovedBias",
    "RunFeatures",
    "RunScore",
    "Scaling",
    "Term",
    "ValidRange",
    "ZeroConfig",
    "ZeroSeries",
    "ZeroStatus",
    "default_scaling",
    "features",
    "fit",
    "fit_per_run",
    "get_model",
    "leave_one_out",
    "load_calibration",
    "mean_coefficients",
    "parse_calibration",
    "read_calibration",
    "removed_bias",
    "score",
    "zero_series",
]


# the offline names, imported on first use (PEP 562): the daemon never loads them
__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
