"""The diagnosis' detection floor (:mod:`gyrotherm.analysis._floor`): the held-out gain
below which a structure in T, ΔT or time is not resolvable at this readout, checked
against the truth's own gain (the oracle: the injected shape's true form fitted) on a
development seed (SHAPE_DEV_SEEDS[0] = 31)."""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._diagnose import Diagnosis
from gyrotherm.analysis._null_replay import replay_spline, replay_splines
from gyrotherm.analysis._report import write_report
from gyrotherm.analysis._resolve import lag_limit
from gyrotherm.analysis._unexplained import VARIABLES
from gyrotherm.analysis.synth._variants import variant_runs

from .conftest import CORNER_CFG, load_script, prepared_selector

DEV = 31
FINE_CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0)  # the sweep's reference readout


@pytest.fixture(scope="module")
def oracle() -> ModuleType:
    return load_script("readout_oracle")


def _periodic(cfg: SynthConfig, amplitude_dps: float, n_runs: int
              ) -> tuple[Diagnosis, dict[str, dict[str, float]]]:
    runs, truth = variant_runs(cfg, shapes={"periodic_t": {"amplitude_dps": amplitude_dps}},
                               n_runs=n_runs, seed=DEV)
    return diagnose(runs, simulate=False), dict(truth.shapes)


@pytest.fixture(scope="module")
def corner_small() -> tuple[Diagnosis, dict[str, dict[str, float]]]:
    return _periodic(CORNER_CFG, 0.005, 3)


@pytest.fixture(scope="module")
def corner_large() -> tuple[Diagnosis, dict[str, dict[str, float]]]:
    return _periodic(CORNER_CFG, 0.03, 3)


def _floor(d: Diagnosis, variable: str) -> float:
    (f,) = [f for f in d.floors if f.variable == variable]
    return f.gain


def test_a_structure_below_the_floor_is_not_reported_and_one_far_above_is(
    oracle: ModuleType, corner_small: tuple[Diagnosis, dict[str, dict[str, float]]],
    corner_large: tuple[Diagnosis, dict[str, dict[str, float]]],
) -> None:
    # a sine in T of 0.005 deg/s at the 1 degC / 1.3 s readout: even its true form,
    # amplitude fitted, gains less than the stated floor, and nothing is reported
    d, shapes = corner_small
    small = oracle.oracle_gain(shapes, d.prepared, d.baseline.scaling)
    assert small < _floor(d, "temperature_c")
    assert not d.unexplained and not d.findings
    # six times larger: far above the floor, and found as a structure in T
    d, shapes = corner_large
    large = oracle.oracle_gain(shapes, d.prepared, d.baseline.scaling)
    assert large > 1.5 * _floor(d, "temperature_c")
    assert [u.variable for u in d.unexplained] == ["temperature_c"]


def test_the_floor_is_the_margin_above_the_readout_replays_and_its_size_in_dps(
    corner_small: tuple[Diagnosis, dict[str, dict[str, float]]],
) -> None:
    d, _ = corner_small
    assert [f.variable for f in d.floors] == list(VARIABLES)
    for f in d.floors:
        assert f.gain == pytest.approx(1.10 * max(1.0, f.null_gain), rel=1e-12)
        # a structure of RMS s on residuals of RMS R gains sqrt(1 + s^2/R^2)
        s = f.rms_dps / d.extended_heldout_rms_dps
        assert math.sqrt(1.0 + s * s) == pytest.approx(f.gain, rel=1e-12)
    out = d.to_dict()["detection_floor"]
    assert [x["variable"] for x in out] == list(VARIABLES)
    assert out[1]["gain"] == d.floors[1].gain


def test_the_coarse_readout_raises_the_floor_in_delta_t(
    corner_small: tuple[Diagnosis, dict[str, dict[str, float]]],
) -> None:
    # at 1 degC the Delta-T estimate jumps 5.9 degC per code change: readout replays
    # without any structure already buy a spline in Delta-T something; at 0.125 degC
    # (the same device and shape) they buy nothing, and the floor is the margin
    fine, _ = _periodic(FINE_CFG, 0.005, 4)
    corner, _ = corner_small
    assert _floor(fine, "delta_t_c") == pytest.approx(1.10, abs=0.01)
    assert _floor(corner, "delta_t_c") > _floor(fine, "delta_t_c") + 0.01


def test_one_replay_serves_every_variable() -> None:
    # replay_splines on the three variables gives each the gains replay_spline gives it
    # alone (the replays depend on the seed, not on the variable)
    runs, _ = variant_runs(CORNER_CFG, n_runs=3, seed=DEV)
    sel, readouts = prepared_selector(runs)
    crossing = lag_limit(readouts, sel.runs).lsb_crossing_s
    every, _ = replay_splines(sel, {}, readouts, crossing, VARIABLES, seed=3)
    for v in VARIABLES:
        alone, _ = replay_spline(sel, {}, readouts, crossing, v, seed=3)
        assert every[v] == alone


def test_the_report_states_the_floor(
    tmp_path: Path, corner_small: tuple[Diagnosis, dict[str, dict[str, float]]],
) -> None:
    d, _ = corner_small
    text = write_report(d, tmp_path).read_text(encoding="utf-8")
    assert "## Detection floor" in text
    for f in d.floors:
        assert f"| {f.variable} | ×{f.gain:.3f} |" in text
