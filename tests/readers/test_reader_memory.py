"""Memory per row of the flight-log readers (tracemalloc: deterministic, not a clock).

A 1-hour 1 kHz log must go through ``fit`` within 1 GB (issue: scale). The run's own
columns are 8 float64 per row (time, T, 3 rates, 3 accelerations: 64 bytes; 40 for the
ULog log, which has no accelerometer samples); what a reader holds at its peak beyond
that is its working set. Measured at 10⁵ rows (166 Hz over the generator's 600 s) on
logs written by ``biglogkit`` (not by the readers), each read once first so that the
imports are not counted, at 888b61e → now: peak 202 → 146 (ULog), 425 → 173 (DataFlash:
pymavlink's index of the log is 36 bytes a message, the numpy gather index a constant
_CHUNK × 51 × 8 bytes), 541 → 275 (MCAP) bytes per row; kept 40 → 40, 100 → 64, 68 → 68.
The bounds sit between the two. Time and RSS at 3.6·10⁶ rows: bench/readers_scale.py,
docs/BENCHMARKS.md "Flight logs".
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest

from biglogkit import SUFFIX, WRITERS
from gyrotherm.readers import InputSpec, read_runs

ROWS = 100_000
#: format → (peak, kept) bytes per row, upper bounds
BOUNDS = {"ulog": (175.0, 48.0), "dataflash": (300.0, 80.0), "mcap": (400.0, 80.0)}


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("biglogs")
    paths = {}
    for fmt, write in WRITERS.items():
        paths[fmt] = out / f"gyro{SUFFIX[fmt]}"
        write(paths[fmt], ROWS, seed=1)
    return paths


@pytest.mark.parametrize("fmt", sorted(BOUNDS))
def test_reader_memory_per_row(logs: dict[str, Path], fmt: str) -> None:
    read_runs(logs[fmt], spec=InputSpec())  # imports and caches: not the reader's cost
    tracemalloc.start()
    try:
        runs = read_runs(logs[fmt], spec=InputSpec())
        kept, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    (run,) = runs
    assert len(run) == ROWS  # every sample read, none lost
    accel = [] if fmt == "ulog" else ["accel_x_mps2", "accel_y_mps2", "accel_z_mps2"]
    assert sorted(run.extra) == accel  # the ULog log has no sensor_accel samples
    peak_bound, kept_bound = BOUNDS[fmt]
    assert peak / ROWS < peak_bound, f"{fmt}: peak {peak / ROWS:.0f} B/row"
    assert kept / ROWS < kept_bound, f"{fmt}: kept {kept / ROWS:.0f} B/row"
