"""Fixtures shared by the analysis tests."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis._prep import (
    Readout,
    characterise,
    estimator_for,
    fit_tau,
    prepare,
    with_tau,
)
from gyrotherm.analysis._score import Selector
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def load_script(name: str) -> ModuleType:
    """``scripts/<name>.py`` as a module named ``name`` (registered in ``sys.modules``:
    its dataclasses look their module up)."""
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def prepared_selector(runs: Sequence[Run], axis: str = "x"
                      ) -> tuple[Selector, list[Readout]]:
    """The selector ``diagnose`` builds on ``runs`` (readouts characterised, the estimator
    they call for, τ fitted from the chamber column), and the readouts."""
    readouts = [characterise(r, axis) for r in runs]
    est = estimator_for(readouts)
    prepared = [prepare(r, axis, est) for r in runs]
    tau = fit_tau(prepared)
    assert tau is not None
    prepared = [with_tau(p, tau[0]) for p in prepared]
    return Selector(prepared, Scaling.from_data(
        np.concatenate([p.temperature_c for p in prepared]),
        np.concatenate([p.delta_t_c for p in prepared]))), readouts


CORNER_CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0, readout_lsb_c=1.0,
                         readout_period_s=1.3)
"""The sweep's corner readout (10 Hz, 1 °C held 1.3 s), diagnosed on 3 runs."""


@pytest.fixture(scope="session")
def sweep() -> ModuleType:
    """``scripts/generalisation_sweep.py`` as a module (its seeds, cases and conditions)."""
    return load_script("generalisation_sweep")


@pytest.fixture(scope="session")
def deployed_gain() -> ModuleType:
    """``scripts/deployed_gain.py`` as a module."""
    return load_script("deployed_gain")


@pytest.fixture(scope="session")
def correction_gain() -> ModuleType:
    """``scripts/correction_gain.py`` as a module."""
    return load_script("correction_gain")
