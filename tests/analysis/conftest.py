"""Fixtures shared by the analysis tests."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

SWEEP_SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "generalisation_sweep.py"


@pytest.fixture(scope="session")
def sweep() -> ModuleType:
    """``scripts/generalisation_sweep.py`` as a module (its seeds, cases and conditions)."""
    spec = importlib.util.spec_from_file_location("generalisation_sweep", SWEEP_SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["generalisation_sweep"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module
