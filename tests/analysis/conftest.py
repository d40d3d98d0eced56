"""Fixtures shared by the analysis tests."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

from gyrotherm.analysis import SynthConfig

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
