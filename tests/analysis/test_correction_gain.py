"""Correction gain (scripts/correction_gain.py): the calibration without its correction
is the same calibration with only the correction gone; the gains, the criterion and the
tables on hand-made cells (a cell without a correction is counted, never dropped). The
study itself (the diagnosis, the daemon) is the daemon test's
(tests/daemon/test_correction_daemon.py) at one seed, and docs/findings.md §6 at five."""

from __future__ import annotations

from dataclasses import replace
from types import ModuleType
from typing import Any

from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.compensation._correction import Correction
from gyrotherm.compensation._effects import Drift, Effects
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import chamber_runs


def test_without_correction_keeps_everything_else(correction_gain: ModuleType) -> None:
    est = EstimatorConfig(tau_s=120.0)
    runs = chamber_runs([10, 40], seed=3, rate_hz=1.0, hold_s=600.0)
    paper: Calibration = fit([features(r, est) for r in runs], "paper", estimator=est)
    corr = Correction("temperature_c", (0.0, 10.0, 20.0), (0.0, 1.0, -1.0))
    drift = Drift(slope_dps_per_h=0.01, t_on_max_s=600.0)
    cal = replace(paper, effects={"x": Effects(drift=drift, correction=corr),
                                  "y": Effects(correction=corr)})
    out = correction_gain.without_correction(cal)
    assert out.effects_of("x") == Effects(drift=drift)
    assert out.effects_of("y").correction == corr
    assert out.coefficients == cal.coefficients and out.estimator == cal.estimator
    assert correction_gain.without_correction(out, "y").effects == {"x": Effects(drift=drift)}


def _row(seed: int, off: tuple[float, float] | None, dep: tuple[float, float] = (1.0, 1.0),
         loro: float = 2.0) -> dict[str, Any]:
    """A cell with RMS values (without, with) offline and deployed; ``off`` None: the
    diagnosis named no unexplained structure."""
    row: dict[str, Any] = {"shape": "bias_step", "seed": seed, "found": [],
                           "unexplained": [], "correction": None}
    if off is None:
        return row

    def s(without: float, with_: float) -> dict[str, dict[str, float]]:
        return {"without": {"rms": without, "rms_offset_removed": without, "mean": 0.0},
                "with": {"rms": with_, "rms_offset_removed": with_, "mean": 0.0}}

    scores = {"rows": 10, "offline": s(*off), "deployed": s(*dep)}
    row.update(unexplained=[{"variable": "temperature_c", "gain": loro}],
               correction={"variable": "temperature_c", "knots": 8, "loro_gain": loro},
               no_zero=scores, zero={"60.0": scores})
    return row


def test_gains_criterion_and_tables(correction_gain: ModuleType) -> None:
    """Offline gain 2 on both cells with a correction; deployed 2 and 1.5 (100 %, 75 %);
    the third cell has none: criterion met 1/3, ≥ 80 % of the LORO gain (2) 1/3."""
    cg = correction_gain
    rows = [_row(3, None), _row(2, (0.02, 0.01), (0.015, 0.01)), _row(1, (0.02, 0.01),
                                                                      (0.02, 0.01))]
    assert [cg.met(r) for r in rows] == [False, False, True]
    assert cg.ratio(rows[1]) == 0.75 and cg.vs_loro(rows[2]) == 1.0
    cells = cg.cell_table(rows)
    assert cells[2].startswith("| bias_step | 1 | temperature_c | 2.00 | 2.00 | 2.00 | 100 % |")
    assert cells[4] == ("| bias_step | 3 | no unexplained | no correction deployed | — | — | "
                        "— | no | — | — |")
    mean, zero = cg.summary_table(rows)[2:]
    assert mean == ("| bias_step | mean | 3 | 1 | 2.00 [2.00–2.00] | 2.00 [2.00–2.00] | "
                    "1.75 [1.50–2.00] | 88 % [75–100] | 1/3 | 88 % [75–100] | 1/3 |")
    assert zero.startswith("| bias_step | zero 60 s | 3 | 1 |")
