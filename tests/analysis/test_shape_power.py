"""The shape check's power and the memory effects' note (issue 19 item 2, round 7):
:func:`gyrotherm.analysis._shape_check._power`, the alternative's generating model
(:func:`gyrotherm.analysis._null_replay._alternative`) and the diagnosis on development
seeds (shapes-dev2, the catalogue's dev seeds) only."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._null_replay import Alternative, _alternative
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._shape_check import SHAPE_MARGIN, _power
from gyrotherm.analysis.synth._variants import variant_runs

from .conftest import CORNER_CFG

FINE = SynthConfig(duration_s=6000.0, rate_hz=10.0)  # the sweep's 0.125 °C / 1.28 s readout
HALF = SynthConfig(duration_s=6000.0, rate_hz=50.0, readout_lsb_c=0.5, readout_period_s=1.0)
"""The sweep's 50 Hz, 0.5 °C / 1.0 s readout, diagnosed on 3 runs."""


def test_power_by_hand() -> None:
    # replays of the catalogued form give ×1.02 and ×1.04: the check needs 1.03 × 1.04
    # = ×1.0712; replays of the alternative give ×1.08 and ×1.05, so one of two is told
    # apart and the shape is not resolvable
    nulls = lambda *_: (1.02, 1.04)  # noqa: E731
    v = _power("gradient_quadratic", "delta_t_c", 9, 1.01, nulls, lambda *_: (1.08, 1.05))
    assert v is not None and v.effect == "shape:gradient_quadratic"
    assert v.params["null_ratio"] == 1.04 and v.params["alternative_ratio"] == 1.05
    assert v.params["told_apart"] == 1.0 and v.params["replays"] == 2.0
    assert "k·|ΔT|" in v.reason and "×1.071" in v.reason and "1/2" in v.reason
    assert (1.0 + SHAPE_MARGIN) * 1.04 == pytest.approx(1.0712)
    # both above ×1.0712: the check would tell them apart, so no verdict
    assert _power("gradient_quadratic", "delta_t_c", 9, 1.01, nulls,
                  lambda *_: (1.08, 1.072)) is None
    # the catalogued form's replays when already made are used, not made again
    made: list[str] = []

    def replay(*_: object) -> tuple[float, ...]:
        made.append("null")
        return (1.0,)

    v = _power("thermal_lag", "delta_t_c", 9, 0.9, replay, lambda *_: (0.95, 0.99),
               nulls=(0.97,))
    assert made == [] and v is not None and v.params["null_ratio"] == 0.97
    assert "A·tanh(ΔT/s)" in v.reason


def test_the_alternative_that_is_the_catalogued_form_generates_the_model_with_it() -> None:
    # with c·ΔT² itself as the only candidate, the joint fit of the model's prediction by
    # the rest's columns and the candidate is that prediction: the generating model is
    # the model with the effect, to rounding
    runs, _ = variant_runs(replace(FINE, effects={"gradient_quadratic": {}}), n_runs=3,
                           seed=1)
    d = diagnose(runs, simulate=False)
    sel = Selector(list(d.prepared), d.baseline.scaling)
    rest = sel.evaluate({})
    full = sel.evaluate({"gradient_quadratic": 0.0})
    coef, extra, noise = _alternative(
        sel, {}, rest, Alternative({"gradient_quadratic": 0.0}, lambda dt: [dt**2]))
    assert noise == pytest.approx(np.sqrt(full.rss / full.n))
    from gyrotherm.analysis._effects import design
    for p, add, r in zip(sel.runs, extra, sel.residuals(full.effects, full.coefficients),
                         strict=True):
        _, x = design(p.time_s, p.temperature_c, p.delta_t_c, sel.scaling, rest.effects)
        generated = x @ coef + add
        predicted = (p.rate_dps - p.rate_dps.mean()) - r
        assert np.max(np.abs((generated - generated.mean()) - predicted)) < 1e-9
    # a candidate of another shape (|ΔT|) does not reproduce it
    coef2, extra2, _ = _alternative(
        sel, {}, rest, Alternative({"gradient_quadratic": 0.0}, lambda dt: [np.abs(dt)]))
    p = sel.runs[0]
    _, x = design(p.time_s, p.temperature_c, p.delta_t_c, sel.scaling, rest.effects)
    generated = x @ coef2 + extra2[0]
    predicted = (p.rate_dps - p.rate_dps.mean()) - sel.residuals(
        full.effects, full.coefficients)[0]
    assert np.max(np.abs((generated - generated.mean()) - predicted)) > 1e-4


def test_a_saturating_response_named_a_lag_gets_the_note() -> None:
    # shapes-dev2 seed 47 at 0.5 °C: A·tanh(G/s) is named thermal_lag; a spline in ΔT in the
    # lag's place does as well held out (×0.994), where on replays of an exact lag it does
    # ×0.83: the lag's memory is not in the data, so the finding says the shape differs
    runs, truth = variant_runs(HALF, shapes={"saturating_dt": {}}, n_runs=3, seed=47)
    assert set(truth.shapes) == {"saturating_dt"}
    d = diagnose(runs, simulate=False)
    (f,) = d.findings
    assert f.effect == "thermal_lag"
    assert "does as well held out" in f.shape and "is not in the data" in f.shape
    assert "odd in ΔT" in f.shape
    assert not any(v.effect.startswith("shape:") for v in d.not_resolvable)


@pytest.mark.parametrize("effect", ["hysteresis", "thermal_lag"])
def test_an_exact_memory_effect_gets_no_note(effect: str) -> None:
    # the catalogue's own hysteresis and lag at 0.5 °C (dev seed 1): the spline in ΔT in
    # their place does worse on the runs as on the replays, so no note
    runs, _ = variant_runs(replace(HALF, effects={effect: {}}), n_runs=3, seed=1)
    d = diagnose(runs, simulate=False)
    found = {f.effect: f for f in d.findings}
    assert effect in found and found[effect].shape == ""


def test_abs_dt_named_gradient_quadratic_at_the_corner_is_declared_by_the_power() -> None:
    # shapes-dev2 seed 48 at the corner: |ΔT| is named c·ΔT², the spline in its place is not
    # better held out, and on replays with k·|ΔT| of the same size the check cannot tell
    # them apart either: the shape is declared not resolvable at this readout
    runs, _ = variant_runs(CORNER_CFG, shapes={"abs_dt": {}}, n_runs=3, seed=48)
    d = diagnose(runs, simulate=False)
    (f,) = d.findings
    assert f.effect == "gradient_quadratic" and f.shape == ""
    (v,) = [v for v in d.not_resolvable if v.effect == "shape:gradient_quadratic"]
    assert v.params["told_apart"] < v.params["replays"] == 2.0
    assert v.params["alternative_ratio"] < (1.0 + SHAPE_MARGIN) * v.params["null_ratio"]
    assert v.params["ratio"] < 1.0 + SHAPE_MARGIN
    assert "cannot be told from k·|ΔT| at this readout" in v.reason


def test_an_exact_gradient_quadratic_at_a_fine_readout_is_resolvable() -> None:
    # the catalogue's c·ΔT² at 0.125 °C (dev seed 1): replays with k·|ΔT| of the same size
    # are told apart, so neither a note nor a verdict
    runs, _ = variant_runs(replace(FINE, effects={"gradient_quadratic": {}}), n_runs=4,
                           seed=1)
    d = diagnose(runs, simulate=False)
    (f,) = d.findings
    assert f.effect == "gradient_quadratic" and f.shape == ""
    assert not [v for v in d.not_resolvable if v.effect.startswith("shape:")]
