"""Shared fixtures: small, seeded simulated chamber runs (cached per session)."""

from __future__ import annotations

import pytest

from gyrotherm.codecs import Run
from gyrotherm.compensation import RunFeatures, features
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import PAPER_HEATING_MIN, GyroParams, chamber_runs

#: Low-rate runs keep the suite fast; the physics is the paper's experiment.
RATE_HZ = 2.0


@pytest.fixture(scope="session")
def gyro() -> GyroParams:
    return GyroParams()


@pytest.fixture(scope="session")
def estimator(gyro: GyroParams) -> EstimatorConfig:
    return EstimatorConfig(tau_s=gyro.tau_s)


@pytest.fixture(scope="session")
def paper_runs() -> list[Run]:
    """The paper's seven heating runs (5…60 min), seed 1, 2 Hz."""
    return chamber_runs(PAPER_HEATING_MIN, seed=1, rate_hz=RATE_HZ)


@pytest.fixture(scope="session")
def validation_run() -> Run:
    return chamber_runs([60], seed=1, rate_hz=RATE_HZ, validation=True)[0]


@pytest.fixture(scope="session")
def paper_features(paper_runs: list[Run], estimator: EstimatorConfig) -> list[RunFeatures]:
    return [features(r, estimator) for r in paper_runs]


@pytest.fixture(scope="session")
def validation_features(validation_run: Run, estimator: EstimatorConfig) -> RunFeatures:
    return features(validation_run, estimator)
