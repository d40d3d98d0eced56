"""Fixtures shared by the export tests: simulated chamber runs and a calibration."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import write_run
from gyrotherm.sim import chamber_runs


@pytest.fixture(scope="module")
def chamber_fit(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path], Path, Path]:
    """(directory, three heating runs, a separate validation run, the fitted cal.json)."""
    d = tmp_path_factory.mktemp("export")
    train = [write_run(r, d / f"{r.name}.csv")
             for r in chamber_runs([10, 30, 60], seed=5, rate_hz=2.0, hold_s=900.0)]
    valid = write_run(chamber_runs([45], seed=5, rate_hz=2.0, hold_s=900.0,
                                   validation=True)[0], d / "valid.csv")
    cal = d / "cal.json"
    assert main(["-q", "fit", *map(str, train), "--out", str(cal), "--no-validation"]) == 0
    return d, train, valid, cal
