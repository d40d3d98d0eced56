"""fit and diagnose --calibration on nothing to find (scripts/null_bound.py): the identity
check and the ratio on hand-made calibrations and scores, and the tables on hand-made
rows. The study itself is docs/findings.md §6 (five seeds); the two commands writing the
same file on null data is tests/cli/test_fit_matches_diagnose.py."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.compensation._effects import Drift, Effects
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import chamber_runs

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "null_bound.py"


@pytest.fixture(scope="module")
def nb() -> ModuleType:
    spec = importlib.util.spec_from_file_location("null_bound", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["null_bound"] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def paper() -> Calibration:
    est = EstimatorConfig(tau_s=120.0)
    runs = chamber_runs([10, 40], seed=3, rate_hz=1.0, hold_s=600.0)
    return fit([features(r, est) for r in runs], "paper", estimator=est)


def _scaled(cal: Calibration, factor: float) -> Calibration:
    return replace(cal, coefficients={a: tuple(factor * c for c in v)
                                      for a, v in cal.coefficients.items()})


def test_identical_to_1e_9_and_without_effects(nb: ModuleType, paper: Calibration) -> None:
    assert nb.identical(paper, paper)
    assert nb.identical(paper, _scaled(paper, 1.0 + 1e-12))
    assert not nb.identical(paper, _scaled(paper, 1.0 + 1e-6))
    assert not nb.identical(paper, replace(paper, estimator=replace(paper.estimator,
                                                                      tau_s=60.0)))
    drift = Drift(slope_dps_per_h=0.01, t_on_max_s=600.0)
    with_drift = replace(paper, effects={"x": Effects(drift=drift)})
    assert not nb.identical(paper, with_drift)
    assert not nb.identical(with_drift, with_drift)  # effects: not the paper calibration
    assert nb.named(with_drift) == ["x:drift"] and nb.named(paper) == []
    assert nb.max_rel_diff(paper, _scaled(paper, 1.5)) == pytest.approx(1 / 3)


def test_ratio_is_diagnose_over_fit_offset_removed(nb: ModuleType) -> None:
    scores = {"fit": {"rms": 9.0, "rms_offset_removed": 2.0, "mean": 1.0},
              "diagnose": {"rms": 1.0, "rms_offset_removed": 2.1, "mean": 0.0}}
    assert nb.ratio(scores) == pytest.approx(1.05)
    assert nb.ratio(scores, "rms") == pytest.approx(1 / 9)


def _row(refresh: float, seed: int, ratio: float, found: list[str]) -> dict[str, Any]:
    return {"refresh_s": refresh, "lsb_c": 0.25, "seed": seed, "ratio": ratio,
            "identical": not found, "found": found, "unexplained": [],
            "effects_cli": [f"x:{f}" for f in found],
            "scores": {"fit": {"rms_offset_removed": 0.01}}}


def test_tables_count_every_seed(nb: ModuleType) -> None:
    rows = [_row(0.1, 2, 1.0, []), _row(0.1, 1, 1.05, ["drift"]), _row(1.28, 1, 0.99, ["cubic"])]
    table = nb.cell_table(rows)
    assert table[2] == ("| 0.1 | 0.25 | 2 | 1/2 | 1.0250 | 1.0500 | 1 | 0.0100 | "
                        "1: named drift; file: x:drift (×1.050) |")
    assert table[3].startswith("| 1.28 | 0.25 | 1 | 0/1 | 0.9900 | 0.9900 | 0 |")
    assert nb.overall(rows).startswith("ratio ≤ 1.03: 2/3 (cell, seed); identical 1/3; "
                                       "worst ×1.0500 (refresh 0.1 s, LSB 0.25 °C, seed 1)")
