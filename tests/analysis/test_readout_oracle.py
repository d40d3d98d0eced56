"""scripts/readout_oracle.py: the held-out gain of an injected shape's true form on the
readout's variables, against hand-built runs whose answer is known."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest

from gyrotherm.analysis._effects import design
from gyrotherm.analysis._prep import Prepared
from gyrotherm.compensation import Scaling

from .conftest import load_script

SAT = {"saturating_dt": {"amplitude_dps": 0.05, "scale_c": 1.5}}


@pytest.fixture(scope="module")
def oracle() -> ModuleType:
    return load_script("readout_oracle")


def _runs(seed: int, shape_dps: float, noise_dps: float) -> list[Prepared]:
    rng = np.random.default_rng(seed)
    out = []
    for r in range(3):
        t = np.arange(3000.0)
        temp = 25.0 + 10.0 * np.sin(2 * np.pi * t / (1500.0 + 200 * r))
        dt = 120.0 * np.gradient(temp)
        rate = (0.01 + 1e-4 * temp + shape_dps * np.tanh(dt / 1.5)
                + noise_dps * rng.standard_normal(len(t)))
        out.append(Prepared(name=f"r{r}", time_s=t, temperature_c=temp, rate_c_per_s=dt / 120,
                            delta_t_c=dt, chamber_c=None, rate_dps=rate,
                            counts=np.ones(len(t)), direction=np.zeros(len(t))))
    return out


def _scaling(runs: list[Prepared]) -> Scaling:
    return Scaling.from_data(np.concatenate([p.temperature_c for p in runs]),
                             np.concatenate([p.delta_t_c for p in runs]))


def test_a_shape_that_is_there_buys_what_its_noise_allows(oracle: ModuleType) -> None:
    # rate = linear in T + 0.05·tanh(ΔT/1.5) + white noise σ = 0.005: with the true column
    # the held-out RMS is σ's; without it, √(r² + σ²), r the RMS of what the paper model
    # (least squares, one offset per run) leaves of the noiseless tanh
    sigma = 0.005
    runs = _runs(1, 0.05, sigma)
    scaling = _scaling(runs)
    clean = _runs(1, 0.05, 0.0)
    xs, ys = [], []
    for p in clean:
        _, x = design(p.time_s, p.temperature_c, p.delta_t_c, scaling, {})
        xs.append(x - x.mean(axis=0))
        ys.append(p.rate_dps - p.rate_dps.mean())
    x, y = np.vstack(xs), np.concatenate(ys)
    r = float(np.sqrt(np.mean((y - x @ np.linalg.lstsq(x, y, rcond=None)[0]) ** 2)))
    expected = float(np.sqrt(r**2 + sigma**2) / sigma)
    assert oracle.oracle_gain(SAT, runs, scaling) == pytest.approx(expected, rel=0.05)
    assert expected > 2.0
    zero = [np.zeros(len(p)) for p in runs]
    assert oracle.heldout_gain(runs, scaling, zero) == pytest.approx(1.0, abs=1e-9)


def test_a_shape_that_is_not_there_buys_nothing(oracle: ModuleType) -> None:
    runs = _runs(2, 0.0, 0.005)
    gain = oracle.oracle_gain(SAT, runs, _scaling(runs))
    assert 0.97 < gain < 1.03


def test_no_shape_no_oracle(oracle: ModuleType) -> None:
    runs = _runs(3, 0.0, 0.005)
    assert oracle.oracle_gain({}, runs, _scaling(runs)) is None


def test_misses_split_by_what_a_proxy_named_buys(sweep: ModuleType) -> None:
    """The sweep's oracle table: a miss above ×1.10 whose named catalogued proxy buys at
    least the oracle's gain (within the shape note's 3 %) is counted apart; a proxy of
    another case, or one buying less, is not. Rows by hand."""
    cond = sweep.CONDITIONS[2].name

    def row(case: str, named: list[tuple[str, float]], oracle: float) -> dict[str, object]:
        return {"case": case, "condition": cond, "missed": ["x"], "oracle_gain": oracle,
                "named": [{"name": n, "gain": g} for n, g in named]}

    rows = [
        row("abs_dt", [("gradient_quadratic", 1.76)], 1.77),  # within 3 %: counted
        row("saturating_dt", [("thermal_lag", 1.10)], 1.20),  # buys less: not
        row("periodic_t", [("gradient_quadratic", 2.0)], 1.30),  # not periodic_t's proxy
        row("saturating_dt", [], 1.05),  # below the readout
    ]
    assert sweep._proxy_gain(rows[0]) == 1.76
    assert sweep._proxy_gain(rows[2]) == 0.0
    line = next(x for x in sweep._oracle(rows, [cond]) if x.startswith(f"| {cond}"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    # shapes, found, missed, below, the method's, of these a proxy buys as much
    assert cells[1:7] == ["4", "0", "4", "1", "3", "1"]


def test_the_gain_left_over_a_chosen_model(oracle: ModuleType) -> None:
    # over the paper model with no effect added it is the oracle gain itself; with a drift
    # (a column in time the tanh in dT does not resemble) about the same is left
    runs = _runs(4, 0.05, 0.005)
    scaling = _scaling(runs)
    plain = oracle.oracle_gain(SAT, runs, scaling)
    assert oracle.oracle_gain(SAT, runs, scaling, effects={}) == plain
    left = oracle.oracle_gain(SAT, runs, scaling, effects={"drift": 0.0})
    assert left == pytest.approx(plain, rel=0.05) and left != plain


def test_the_floor_columns_of_the_oracle_table(sweep: ModuleType) -> None:
    """Rows by hand: a miss the floor declared and a structure found below the floor are
    counted in their own columns, not in "found" or the verdicts'."""
    cond = sweep.CONDITIONS[3].name
    rows = [
        {"case": "saturating_dt", "condition": cond, "missed": ["unexplained:delta_t_c"],
         "oracle_gain": 1.03, "named": [], "missed_below_floor": ["unexplained:delta_t_c"],
         "found_below_floor": []},
        {"case": "abs_dt", "condition": cond, "missed": [], "oracle_gain": 1.05, "named": [],
         "missed_below_floor": [], "found_below_floor": ["unexplained:delta_t_c"]},
        {"case": "periodic_t", "condition": cond, "missed": ["unexplained:temperature_c"],
         "oracle_gain": 1.20, "named": [], "missed_below_floor": [], "found_below_floor": []},
    ]
    line = next(x for x in sweep._oracle(rows, [cond]) if x.startswith(f"| {cond}"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    # shapes, found, missed, below x1.10, the method's, proxy as much, below the floor,
    # found below the floor
    assert cells[1:9] == ["3", "1", "2", "1", "1", "0", "1", "1"]


def test_floor_of_a_name(sweep: ModuleType) -> None:
    floors = {"temperature_c": 1.12, "delta_t_c": 1.31, "time_since_power_on_s": 1.2}
    assert sweep.floor_of("unexplained:delta_t_c", floors, 0.10) == 1.31
    assert sweep.floor_of("warmup", floors, 0.10) == pytest.approx(1.10)
    assert sweep.floor_of("hysteresis", floors, 0.05) == pytest.approx(1.05)
