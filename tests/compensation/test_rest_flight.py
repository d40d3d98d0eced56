"""Rest detection on flight-like runs: a whole run turning, logging gaps, armed rows, a
still run shorter than the default minimum rest stretch (issue 18, item 3).

Independent truth: the rates, gaps and armed periods are generated here, so which row
turns, which follows a gap and which is armed is known row by row."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gyrotherm.codecs import Run
from gyrotherm.compensation._rest import RestConfig, detect_rest, rest_of_run
from gyrotherm.readers import InputSpec, parse_columns, read_runs
from gyrotherm.sim import chamber_runs


def _turning_throughout(rate_hz: float = 10.0, duration_s: float = 780.0) -> Run:
    """780 s at 10 Hz (7801 rows) of a vehicle turning all the time, up to 90 °/s: the
    sum of slow sines on each axis, never still for more than a moment."""
    rng = np.random.default_rng(18)
    t = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    rates = {}
    for k, axis in enumerate("xyz"):
        f1, f2 = 0.013 * (k + 1), 0.071 * (k + 2)
        rates[axis] = (60.0 * np.sin(2 * np.pi * f1 * t + k) + 30.0 * np.sin(2 * np.pi * f2 * t)
                       + rng.standard_normal(len(t)) * 0.05)
    return Run(name="turning", time_s=t, temperature_c=30.0 + 0.01 * t, rates_dps=rates)


def test_a_run_turning_throughout_keeps_no_turning_row() -> None:
    """Found by a colleague: all 7801 rows of such a run were kept as rest (the robust
    statistics take the log's own level as 'rest' when nothing in it is still)."""
    run = _turning_throughout()
    assert len(run) == 7801
    mag = np.sqrt(sum(v**2 for v in run.rates_dps.values()))
    assert mag.max() > 85.0
    report = rest_of_run(run)
    assert not np.any(report.rest & (mag > 5.0))
    # moments of a sine through zero are not rest either: they are short and between turns
    assert report.rest.sum() == 0
    assert report.segments and report.excluded_fraction == 1.0


def test_a_still_run_shorter_than_the_default_minimum_is_kept_and_said_why() -> None:
    """Found by a colleague: a gyro still for 25 s (less than the 30-s minimum rest
    stretch) had every row excluded as 'short rest'."""
    (long,) = chamber_runs([5], seed=3, rate_hz=10.0, hold_s=600.0)
    short = long.slice(0, 251)  # 25 s at 10 Hz, at rest throughout
    assert short.time_s[-1] - short.time_s[0] < RestConfig().min_segment_s
    report = rest_of_run(short)
    assert report.rest.all()
    assert report.min_segment_s < RestConfig().min_segment_s
    assert "shorter than" in report.note and "25" in report.note


def test_a_logging_gap_ends_a_rest_stretch() -> None:
    """Two still stretches of 20 s each around a 35-s gap: 40 s of rows but no stretch of
    30 s. Rows after the gap turn at 180 °/s for 2 s (a turn partly in the gap): the gap
    did count toward the 30-s minimum and such rows were kept."""
    rng = np.random.default_rng(2)
    before = np.arange(0.0, 20.0, 0.01)
    after = np.arange(55.0, 75.0, 0.01)
    t = np.concatenate([np.arange(-300.0, -200.0, 0.01), before, after])
    x = rng.standard_normal(len(t)) * 0.05
    x[(t >= 55.0) & (t < 57.0)] += 180.0
    report = detect_rest(t, {"x": x})
    in_gap_pieces = (t >= 0.0)
    assert not report.rest[in_gap_pieces].any()  # neither 20-s piece reaches 30 s alone
    assert report.rest[t < -200.0].all()  # the long still stretch before stays
    assert any("logging gap" in s.reasons for s in report.segments)


def test_armed_rows_are_not_rest_even_when_still() -> None:
    """A vehicle armed on the ground (SITL, or motors idling on a soft mount) shows no
    turn; the log's armed state still takes those rows out."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 300.0, 0.1)
    rates = {a: rng.standard_normal(len(t)) * 0.05 for a in "xyz"}
    armed = ((t >= 100.0) & (t < 160.0)).astype(np.float64)
    report = detect_rest(t, rates, armed=armed)
    assert not report.rest[armed > 0].any()
    assert report.rest[(t < 98.0) | (t > 162.0)].all()
    assert any("armed" in s.reasons for s in report.segments)


_BMI270 = Path("data/measured/bmi270-peltier-laptop/bmi270_static_clean.csv")
BMI270 = next((d / _BMI270 for d in (Path(__file__).resolve().parents[3] / "shared",
                                     Path("/work/shared")) if (d / _BMI270).is_file()),
              Path("/work/shared") / _BMI270)


@pytest.mark.skipif(not BMI270.is_file(), reason="shared measured data not present")
def test_a_real_still_board_in_a_fan_draught_is_not_cut_by_the_physical_limits() -> None:
    """The project's BMI270 file (its SOURCE.md: the board kept stationary, the hot plateau
    in a laptop's exhaust) has 1-s blocks whose rate spread reaches 1.3 °/s: the physical
    limits (2 °/s spread, 5 °/s rate) leave them to the statistics, which keep what they
    kept before the limits existed (2500 of 3255 and 4900 of 6533 rows: a few bumps, up
    to 12.8 °/s, and short stretches at the ends)."""
    runs = read_runs(BMI270, spec=InputSpec(columns=parse_columns(
        "time=t_nominal_s:s temperature=temp_degC:degC x=gyro_x_dps:dps y=gyro_y_dps:dps "
        "z=gyro_z_dps:dps run=segment".split())))
    for run, kept in zip(runs, (2500, 4900), strict=True):
        rest = rest_of_run(run).rest
        assert int(rest.sum()) == kept  # with a 1-°/s spread limit: 3950 of the hot 6533
        mag = np.sqrt(sum(v**2 for v in run.rates_dps.values()))
        assert not np.any(rest & (mag > 5.0))
