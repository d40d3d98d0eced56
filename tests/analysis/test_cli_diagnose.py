"""``gyrotherm diagnose`` through its argparse registration (a local parser)."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

import pytest

from gyrotherm._errors import CalibrationError, RunFileError
from gyrotherm.analysis import SynthConfig, synth_runs
from gyrotherm.cli import _diagnose
from gyrotherm.codecs import write_run


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="command", required=True)
    _diagnose.register(sub)
    return p


def test_cli_writes_schema_json_and_report(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    runs, _ = synth_runs(SynthConfig(duration_s=2400.0, rate_hz=5.0,
                                     effects={"drift": {"slope_dps_per_h": 0.15}}),
                         n_runs=3, seed=9)
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv")) for r in runs]
    out = tmp_path / "out.json"
    args = _parser().parse_args(["diagnose", *paths, "--json", str(out),
                                 "--report", str(tmp_path / "rep")])
    assert args.func(args) == 0
    data = json.loads(out.read_text())
    assert data["schema"] == "gyrotherm.diagnosis/1"
    assert data["axis"] == "x"
    assert data["baseline"]["model"] == "paper"
    assert [f["effect"] for f in data["findings"]] == ["drift"]
    assert data["findings"][0]["params"]["slope_dps_per_h"] == pytest.approx(0.15, rel=0.3)
    assert data["extended"]["gain"] > 1.1
    mismatch = data["simulation"]["mismatch"]
    stats = {m["statistic"] for m in mismatch}
    assert {"drift_dps_per_h", "allan_deviation_10s_dps"} <= stats
    # every statistic against the replays' spread, largest |z| first
    assert data["simulation"]["replays"] == 5
    threshold = data["simulation"]["z_threshold"]
    assert threshold == pytest.approx(7.25, abs=0.01)
    assert [abs(m["z"]) for m in mismatch] == sorted((abs(m["z"]) for m in mismatch),
                                                     reverse=True)
    for m in mismatch:
        assert m["z"] == pytest.approx((m["measured"] - m["sim_mean"]) / m["sim_std"])
        assert m["significant"] == (abs(m["z"]) > threshold)
        assert m["extended_z"] == pytest.approx(
            (m["measured"] - m["extended_mean"]) / m["extended_std"])
    assert data["simulation"]["significant"] == [m["statistic"] for m in mismatch
                                                 if m["significant"]]
    report = (tmp_path / "rep" / "report.md").read_text(encoding="utf-8")
    assert "| statistic | measured | simulated (paper), mean ± std | z | simulated " \
        "(extended), mean ± std | z (extended) |" in report
    assert "Significant mismatches (paper model): " in report
    for name in ("report.md", "measured_vs_simulated.png", "residual_vs_temperature.png",
                 "residual_vs_time.png", "before_after.png"):
        assert (tmp_path / "rep" / name).stat().st_size > 0
    # the detection floor: in the JSON, the report and the summary line, the same figures
    floors = data["detection_floor"]
    assert [f["variable"] for f in floors] == ["temperature_c", "delta_t_c",
                                               "time_since_power_on_s"]
    assert all(f["gain"] >= 1.10 - 1e-12 for f in floors)
    err = capsys.readouterr().err
    assert f"diagnose: found drift (gain {data['findings'][0]['gain']:.2f}); extended" in err
    said = ", ".join(f"×{f['gain']:.2f} in {f['variable']}" for f in floors)
    assert f"diagnose: not resolvable at this readout: a structure gaining less than {said}" \
        in err
    assert "## Detection floor" in report


def test_cli_errors_name_the_problem(tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    runs, _ = synth_runs(SynthConfig(duration_s=900.0, rate_hz=2.0), n_runs=1, seed=1)
    one = str(write_run(runs[0], tmp_path / "one.csv"))
    args = _parser().parse_args(["diagnose", one, "--json", str(tmp_path / "o.json")])
    with pytest.raises(CalibrationError, match="at least 2 runs"):
        args.func(args)
    log = tmp_path / "bus.csv"  # a candump log, whatever its name says
    log.write_text("(1.000000) can0 123#00\n")
    args = _parser().parse_args(["diagnose", one, str(log), "--json", "-"])
    with pytest.raises(CalibrationError, match="at least 2 runs"):  # the good log goes on
        args.func(args)
    assert re.search(r"gyrotherm: error: \S*bus\.csv: candump log has no valid rate frame "
                     r".*unknown_id: 1", capsys.readouterr().err)
    args = _parser().parse_args(["diagnose", one, one, "--json", "-", "--axis", "y"])
    with pytest.raises(RunFileError, match="share a name"):
        args.func(args)


def _corner_abs_dt(tmp_path: Path, capsys: pytest.CaptureFixture[str], seed: int,
                   shape: str = "abs_dt") -> tuple[dict[str, Any], str]:
    """|ΔT| (or ``shape``) on 3 runs at the sweep's 1 °C / 1.3 s corner, written as run
    files and diagnosed through the CLI without the simulator: the JSON and stderr."""
    from gyrotherm.analysis.synth._variants import variant_runs

    runs, _ = variant_runs(SynthConfig(duration_s=6000.0, rate_hz=10.0, readout_lsb_c=1.0,
                                       readout_period_s=1.3),
                           shapes={shape: {}}, n_runs=3, seed=seed)
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv")) for r in runs]
    out = tmp_path / "out.json"
    args = _parser().parse_args(["diagnose", *paths, "--no-simulation", "--json", str(out)])
    assert args.func(args) == 0
    return json.loads(out.read_text()), capsys.readouterr().err


def test_the_summary_names_an_unexplained_structure_and_its_caveat(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the ninth evaluation set's |ΔT| at the corner (seed 464, a used set): the only finding
    # is a structure in time, ΔT not told apart; the summary line must not say "nothing"
    data, err = _corner_abs_dt(tmp_path, capsys, 464)
    (u,) = data["findings"]
    assert u["params"]["variable"] == "time_since_power_on_s"
    assert (f"diagnose: found unexplained in time_since_power_on_s (gain {u['gain']:.2f}; "
            "not told apart from a structure in delta_t_c") in err


def test_the_summary_says_when_a_findings_shape_is_not_resolvable(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # shapes-dev2 seed 48 at the corner: |ΔT| named c·ΔT², its shape declared not
    # resolvable (tests/analysis/test_shape_power.py); the summary line says so beside the
    # finding, not only the progress lines above it
    data, err = _corner_abs_dt(tmp_path, capsys, 48)
    (f,) = data["findings"]
    assert f["effect"] == "gradient_quadratic"
    assert "shape:gradient_quadratic" in {v["effect"] for v in data["not_resolvable"]}
    assert (f"diagnose: found gradient_quadratic (gain {f['gain']:.2f}; its shape is not "
            "resolvable at this readout); extended") in err


def test_the_summary_says_which_catalogued_effects_a_finding_is_not_told_from(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # shapes-dev3 seed 566 at the corner: a rate-dependent hysteresis named a cubic, which
    # hysteresis alone does as well as (tests/analysis/test_catalogued_rivals.py)
    data, err = _corner_abs_dt(tmp_path, capsys, 566, shape="rate_hysteresis")
    (f,) = [f for f in data["findings"] if f["effect"] == "cubic"]
    assert set(f["not_told_from"]) == {"hysteresis"}
    assert (f"diagnose: found cubic (gain {f['gain']:.2f}; not told apart from "
            "hysteresis)") in err
