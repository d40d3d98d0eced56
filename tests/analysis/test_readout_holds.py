"""The readout's refresh period on the generator's chamber runs, whose holds keep a
coarse reading on one value for hundreds of seconds (the table of
``test_readout_table.py`` has ramps and warm-ups only).

Found by ``fleet``'s test (a 1 °C reading refreshed every 0.5 s at 10 Hz came out
0.25 s): unwrapping the refresh count of each gap between changes from a comb
candidate 0.1 % off miscounts a 300-s gap, and the jittered stamps made the shortest
gap a hair under P − one row, so the candidates stopped just below P. Seed 41 below
is where it was found (the cells that missed before the fix); seed 77's are the cells
of a 42-cell grid (LSB 0.0625, 0.25, 1 °C × refresh 0.05, 0.1, 0.25, 0.64, 1.3 s × 10,
50, 200 Hz, 30-min runs) that missed before it (seeds 77–82: 44 misses of 252 before,
0 after; docs/findings.md §6)."""

from __future__ import annotations

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis._prep import (
    _longest_multiple,
    _phase_scan,
    _refresh_from_changes,
    characterise,
)
from gyrotherm.analysis.synth._variants import variant_runs

#: (LSB °C, refresh s, rows Hz) that missed on seed 41 before the fix.
FOUND = ((0.125, 0.1, 50.0), (0.5, 0.1, 50.0), (1.0, 0.1, 50.0), (0.5, 0.5, 10.0),
         (1.0, 0.5, 10.0), (0.5, 0.25, 10.0), (1.0, 0.25, 10.0))
#: (LSB °C, refresh s, rows Hz) of the seed-77 grid that missed before the fix.
GRID = ((0.25, 0.05, 200.0), (0.25, 0.1, 50.0), (1.0, 0.05, 50.0), (1.0, 0.05, 200.0),
        (1.0, 0.1, 50.0), (1.0, 0.1, 200.0), (1.0, 0.25, 10.0))


def _refresh(lsb: float, period: float, hz: float, seed: int, duration_s: float,
             n_runs: int) -> list[tuple[float, float]]:
    cfg = SynthConfig(duration_s=duration_s, rate_hz=hz, readout_lsb_c=lsb,
                      readout_period_s=period)
    runs, _ = variant_runs(cfg, shapes={}, n_runs=n_runs, seed=seed)
    out = []
    for r in runs:
        got = characterise(r, "x")
        out.append((float(got.refresh_period_s or 0.0), got.lsb_c))
    return out


@pytest.mark.parametrize(("lsb", "period", "hz"), FOUND)
def test_seed_41_where_it_was_found(lsb: float, period: float, hz: float) -> None:
    for refresh, got_lsb in _refresh(lsb, period, hz, 41, 3000.0, 2):
        assert refresh == pytest.approx(period, rel=0.10)
        assert got_lsb == pytest.approx(lsb, rel=0.10)


@pytest.mark.parametrize(("lsb", "period", "hz"), GRID)
def test_seed_77_cells_that_missed(lsb: float, period: float, hz: float) -> None:
    ((refresh, got_lsb),) = _refresh(lsb, period, hz, 77, 1800.0, 1)
    assert refresh == pytest.approx(period, rel=0.10)
    assert got_lsb == pytest.approx(lsb, rel=0.10)


def test_a_long_run_of_rare_changes_refines_to_the_refresh() -> None:
    """Hand-built change times: a 0.1-s refresh seen at the first 50-Hz row after it
    (±2 % stamp jitter), 40 changes close together, then one every 100–500 s for 10 h,
    so the run is ~750× longer than the changes the coarse scan sees. The phase scan
    (called directly: here the lattice finds it too) refines over spans 4× longer each
    time and ends on 0.1 s within 1e-6 relative (a step of the run's last change well
    under a row), not on a divisor (0.05 s holds every change too) nor on one row; its
    phase is a refresh instant (3.7 s + k·0.1 s, seen up to a row later)."""
    rng = np.random.default_rng(7)
    dt, refresh = 0.02, 0.1
    rows = np.cumsum(rng.uniform(0.98, 1.02, size=int(36_000 / dt)) * dt)
    k = np.cumsum(np.r_[rng.integers(5, 20, size=40), rng.integers(1000, 5000, size=120)])
    seen = np.unique(np.searchsorted(rows, 3.7 + k * refresh))  # first row after each
    tc = rows[seen[seen < len(rows)]]
    for lo, hi in ((0.09, 0.11), (1.5 * dt, float(np.min(np.diff(tc))) + 1.1 * dt)):
        got, phase = _phase_scan(tc, lo, hi, dt)
        assert got == pytest.approx(refresh, rel=1e-6)
        assert phase is not None
        lag = (phase - 3.7) % refresh  # after the refresh instant, by less than a row
        assert lag < 1.05 * dt or lag > refresh - 0.05 * dt
    assert _refresh_from_changes(rows, seen[seen < len(rows)], dt)[0] == pytest.approx(
        refresh, rel=1e-6)


def test_a_lattice_on_half_the_refresh_is_lifted_to_the_refresh() -> None:
    """A lattice unwrapped from the gaps can settle on P/2 (every change sits on it too;
    the review found 0.25 s for a 0.5-s refresh at 10 Hz): the longest multiple of it,
    up to the longest possible refresh, on which the changes still line up is taken.
    Hand-built: a 0.5-s refresh seen at the first 10-Hz row after it (±2 % jitter),
    changes every 1–40 refreshes for 1 h; from 0.2501 s (P/2, 0.04 % off), 0.5 s."""
    rng = np.random.default_rng(11)
    dt, refresh = 0.1, 0.5
    rows = np.cumsum(rng.uniform(0.98, 1.02, size=int(3600 / dt)) * dt)
    k = np.cumsum(rng.integers(1, 40, size=400))
    seen = np.unique(np.searchsorted(rows, 1.23 + k * refresh))
    tc = rows[seen[seen < len(rows)]]
    hi = float(np.min(np.diff(tc))) + 1.1 * dt
    got, phase = _longest_multiple(tc, 0.2501, 1.23, hi, dt)
    assert got == pytest.approx(refresh, rel=1e-5)
    lag = (phase - 1.23) % refresh  # a refresh instant, the change seen within a row
    assert lag < 1.05 * dt or lag > refresh - 0.05 * dt
    assert _longest_multiple(tc, refresh, 1.23, hi, dt)[0] == refresh  # already the longest
