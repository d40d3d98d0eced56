"""Fixtures for daemon tests: short runs and a calibration fitted on them."""

from __future__ import annotations

import pytest

from gyrotherm.codecs import Run
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs


@pytest.fixture(scope="session")
def short_runs() -> list[Run]:
    """Three short chamber runs (5, 20, 60 min heating, 20 min holds) at 1 Hz."""
    return chamber_runs([5, 20, 60], seed=8, rate_hz=1.0, hold_s=1200)


@pytest.fixture(scope="session")
def stream_calibration(short_runs: list[Run]) -> Calibration:
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    return fit([features(r, est) for r in short_runs], "paper", estimator=est)
