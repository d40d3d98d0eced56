"""The temperature readout's characterisation (refresh period, LSB, white noise) as a
table against the synthetic generator's truth (issue 19, item 4, first bullet).

The grid, its seeds and the pass rules were fixed before any result was looked at:

* refresh P ∈ {0.05, 0.1, 0.32, 0.64, 1.0, 1.3} s × LSB ∈ {0.0625, 0.25, 1} °C ×
  rows at {10, 50, 200} Hz (±2 % stamp jitter) × a slow and a fast temperature change
  × white noise σ ∈ {0, LSB/2, 1.5·LSB} per reading; the cells whose refresh is shorter
  than the row interval (0.05 s at 10 Hz) are dropped: such a readout is one fresh
  reading per row and is no different from a 0.1-s one;
* slow: a chamber ramp, 20 °C + 0.97 °C/min with a 0.3 °C, 400-s wobble (0.7–1.25
  °C/min, never reversing), 30 min;
* fast: a warm-up, 20 + 25·(1 − exp(−t/150 s)) °C (10 °C/min at first, 0.2 °C/min at the
  end), 10 min;
* the readout: :func:`gyrotherm.analysis.synth._synth.read_temperature` (the generator's
  sensor stage); seed 1000 + the cell's index in :func:`cells`.

Pass rules, per cell:

* refresh: ``refresh_period_s`` within 10 % of max(P, row interval);
* LSB: ``lsb_c`` within 10 % of the LSB (every cell is quantised);
* noise: ``white_noise_c`` within 10 % of σ; where σ = 0, at most LSB/10 (a floor: a
  noiseless reading must not be given noise of more than a tenth of its step).

Result at the commit that added this table: refresh 306/306 and LSB 306/306; noise
303/306, the three misses named in :data:`NOISE_SAMPLING_LIMITED` (any other miss, or
one of them passing, fails the test). Before it (the comb of 20fb02e): refresh
287/306, LSB 306/306, noise 288/306.

``python tests/analysis/test_readout_table.py`` prints the table's summary and misses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from gyrotherm.analysis._prep import Readout, characterise
from gyrotherm.analysis.synth._synth import read_temperature, row_times
from gyrotherm.codecs import Run

REFRESH_S = (0.05, 0.1, 0.32, 0.64, 1.0, 1.3)
LSB_C = (0.0625, 0.25, 1.0)
RATE_HZ = (10, 50, 200)
CHANGES = ("slow", "fast")
NOISE_IN_LSB = (0.0, 0.5, 1.5)
SEED0 = 1000
#: The cells the table misses, found when it was first run and kept as a limit (not
#: tuned away): the white noise at σ = LSB/2 on the 10-min warm-up, one reading per
#: 1–1.3 s (460–600 readings), −11 %, +12 % and −15 %. The standard error of σ there is
#: ≈ 4.5 % (σ² from N readings, inflated a third by the LSB²/12 subtracted), so these
#: are 2.5–3.4 standard errors out: a longer run, not the method, would resolve them.
NOISE_SAMPLING_LIMITED = {(1.0, 0.25, 50, "fast", 0.5), (1.3, 0.0625, 10, "fast", 0.5),
                          (1.3, 1.0, 10, "fast", 0.5)}


@dataclass(frozen=True)
class Cell:
    refresh_s: float
    lsb_c: float
    rate_hz: int
    change: str
    noise_c: float
    seed: int


def cells() -> list[Cell]:
    grid = [(p, q, hz, ch, k) for p in REFRESH_S for q in LSB_C for hz in RATE_HZ
            for ch in CHANGES for k in NOISE_IN_LSB if p >= 1.0 / hz]
    return [Cell(p, q, hz, ch, k * q, SEED0 + i) for i, (p, q, hz, ch, k) in enumerate(grid)]


def true_temperature(change: str, t: np.ndarray) -> np.ndarray:
    if change == "slow":
        return np.asarray(20.0 + 0.97 / 60.0 * t + 0.3 * np.sin(2 * np.pi * t / 400.0))
    return np.asarray(20.0 + 25.0 * (1.0 - np.exp(-t / 150.0)))


def readout_run(cell: Cell) -> Run:
    rng = np.random.default_rng(cell.seed)
    t = row_times(cell.rate_hz, 1800.0 if cell.change == "slow" else 600.0, rng)
    reading = read_temperature(t, true_temperature(cell.change, t), period_s=cell.refresh_s,
                               lsb_c=cell.lsb_c, noise_c=cell.noise_c, rng=rng)
    return Run(name="readout", time_s=t, temperature_c=reading,
               rates_dps={"x": rng.normal(0.0, 0.01, len(t))})


def misses(cell: Cell, ro: Readout) -> list[str]:
    """What of ``ro`` is outside the pass rules for ``cell`` (empty: the cell passes)."""
    out = []
    want = max(cell.refresh_s, 1.0 / cell.rate_hz)
    if not abs(ro.refresh_period_s - want) <= 0.1 * want:
        out.append(f"refresh {ro.refresh_period_s:.4g} s")
    if not abs(ro.lsb_c - cell.lsb_c) <= 0.1 * cell.lsb_c:
        out.append(f"lsb {ro.lsb_c:.4g}")
    if cell.noise_c == 0:
        if not ro.white_noise_c <= cell.lsb_c / 10:
            out.append(f"noise {ro.white_noise_c:.4g} > LSB/10")
    elif not abs(ro.white_noise_c - cell.noise_c) <= 0.1 * cell.noise_c:
        out.append(f"noise {ro.white_noise_c:.4g}")
    return out


def table(selected: list[Cell]) -> list[tuple[Cell, list[str]]]:
    return [(c, misses(c, characterise(readout_run(c), "x"))) for c in selected]


@pytest.mark.parametrize("noise_in_lsb", NOISE_IN_LSB)
@pytest.mark.parametrize("change", CHANGES)
def test_readout_characterised_within_10_percent_in_every_cell(change: str,
                                                               noise_in_lsb: float) -> None:
    selected = [c for c in cells()
                if c.change == change and math.isclose(c.noise_c, noise_in_lsb * c.lsb_c)]
    assert len(selected) == 51
    missed = {(c.refresh_s, c.lsb_c, c.rate_hz, c.change, c.noise_c / c.lsb_c): m
              for c, m in table(selected) if m}
    assert set(missed) == {key for key in NOISE_SAMPLING_LIMITED
                           if key[3] == change and key[4] == noise_in_lsb}, missed
    assert all(m[0].startswith("noise") and len(m) == 1 for m in missed.values()), missed


def test_the_grid_is_the_one_fixed_before_the_results() -> None:
    all_cells = cells()
    assert len(all_cells) == (6 * 3 * 3 - 3) * 2 * 3 == 306
    assert not any(c.refresh_s < 1.0 / c.rate_hz for c in all_cells)
    assert [c.seed for c in all_cells] == list(range(1000, 1306))


if __name__ == "__main__":
    rows = table(cells())
    for quantity in ("refresh", "lsb", "noise"):
        bad = sum(any(m.startswith(quantity) for m in ms) for _, ms in rows)
        print(f"{quantity}: {len(rows) - bad}/{len(rows)} within the rule")
    print(f"all three: {sum(not ms for _, ms in rows)}/{len(rows)}")
    for c, ms in rows:
        if ms:
            print(f"  P={c.refresh_s} LSB={c.lsb_c} {c.rate_hz} Hz {c.change} "
                  f"σ={c.noise_c:g}: {', '.join(ms)}")
