"""Off-catalogue shapes of issue 19, must-show item 2: a periodic bias in T, a
saturating and a |ΔT| response to the gradient, a hysteresis whose width grows with
|dT/dt|. Their formulas against hand-computed values, the ``where`` span against the
generator's truth, and the diagnosis of one shape per variable on development seeds.

SHAPE_EVAL_SEEDS are fixed here and in scripts/generalisation_sweep.py before the
shapes existed and before any result on them was seen; they are never used while
developing (tests use SHAPE_DEV_SEEDS only)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

SHAPE_DEV_SEEDS = (31, 32, 33, 34, 35, 36)
SHAPE_EVAL_SEEDS = (301, 302, 303, 304, 305)
"""Fixed (the commit adding this line) before any result on them was seen."""
SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "generalisation_sweep.py"


@pytest.fixture(scope="module")
def sweep() -> ModuleType:
    spec = importlib.util.spec_from_file_location("generalisation_sweep", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["generalisation_sweep"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_shape_eval_seeds_are_fixed_and_disjoint(sweep: ModuleType) -> None:
    assert sweep.SHAPE_DEV_SEEDS == SHAPE_DEV_SEEDS
    assert sweep.SHAPE_EVAL_SEEDS == SHAPE_EVAL_SEEDS
    used = {*sweep.DEV_SEEDS, *sweep.EVAL_SEEDS, *SHAPE_DEV_SEEDS}
    assert not set(SHAPE_EVAL_SEEDS) & used
