"""Compensation: bias models in T and ΔT, least-squares fitting, calibration files,
the online compensator (base polynomial + effects kernels, one per axis), and the
boot-time zero."""

from gyrotherm.compensation._calibration import BiasEstimate, Calibration, ValidRange
from gyrotherm.compensation._calibration_file import (
    load_calibration,
    parse_calibration,
    read_calibration,
)
from gyrotherm.compensation._compensator import CompensatedSeries, Compensator
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
from gyrotherm.compensation._models import MODELS, ModelSpec, Scaling, Term, get_model
from gyrotherm.compensation._zero import BootZero, ZeroConfig, ZeroSeries, ZeroStatus, zero_series

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
