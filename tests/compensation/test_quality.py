"""The fit quality gates' measurements against hand computation (run by run, in blocks:
no copy of every row at once)."""

from __future__ import annotations

import numpy as np
import pytest

from gyrotherm.compensation import RunFeatures, default_scaling, get_model
from gyrotherm.compensation._quality import _rest_temperatures, check, design_condition


def _run(name: str, temp: np.ndarray, rest: np.ndarray | None = None) -> RunFeatures:
    n = len(temp)
    dtemp = np.sin(np.arange(n) / 977.0)
    return RunFeatures(name, "hand", "", np.arange(n) / 100.0, temp, dtemp,
                       {"x": np.zeros(n)}, rest=rest)


def test_distinct_readings_and_span_over_runs_by_hand() -> None:
    a = _run("a", np.array([20.0, 20.5, 21.0, 21.0]))
    b = _run("b", np.array([21.0, 30.0, 99.0]), rest=np.array([True, True, False]))
    n, distinct, span = _rest_temperatures([a, b])
    assert (n, distinct, span) == (6, 4, 10.0)  # {20, 20.5, 21, 30}; 99 is not at rest
    gates = {g.name: g for g in check([a, b], get_model("t2"), validation=False)}
    assert gates["temperature-stuck"].measured == 4 and gates["temperature-span"].measured == 10.0


def test_design_condition_in_blocks_equals_the_whole_matrix() -> None:
    rng = np.random.default_rng(7)  # > 2 blocks of 65 536 rows, one run masked in part
    t1 = 20.0 + np.cumsum(rng.normal(0.0, 0.05, 150_000))
    rest = rng.random(150_000) > 0.3
    runs = [_run("a", t1, rest), _run("b", 35.0 + np.cos(np.arange(70_000) / 5e3))]
    spec = get_model("paper")
    scaling = default_scaling(runs)
    a = np.vstack([spec.design(*scaling.centre(r.rows(r.temperature_c), r.rows(r.delta_t_c)))
                   for r in runs])
    a = a / np.linalg.norm(a, axis=0)
    s = np.linalg.svd(a, compute_uv=False)
    assert design_condition(runs, spec) == pytest.approx(s[0] / s[-1], rel=1e-6)
