"""The offline CLI end to end: sim chamber → fit → evaluate, and error exits."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrotherm.cli import main


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    code = main(["-q", "sim", "chamber", "--heating-min", "5", "30", "60", "--out", str(out),
                 "--seed", "3", "--rate-hz", "1", "--hold-s", "1200"])
    assert code == 0
    return out


def test_sim_fit_evaluate(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = sorted(str(p) for p in run_dir.glob("*.csv"))
    assert [Path(r).name for r in runs] == ["heat-05min.csv", "heat-30min.csv", "heat-60min.csv"]
    capsys.readouterr()
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *runs, "--model", "paper", "--out", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "heat-05min" in out and "T*dT" in out and "Leave-one-run-out" in out
    assert main(["-q", "evaluate", str(cal), runs[0], "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["model"] == "paper"
    assert {s["axis"] for s in doc["scores"]} == {"x", "y", "z"}
    for s in doc["scores"]:
        assert s["compensated"]["rms_dps"] < 0.3 * s["raw"]["rms_dps"]
        assert s["truth"]["rms_dps"] < 0.05


def test_t2_and_paper_average_methods(run_dir: Path, tmp_path: Path) -> None:
    runs = sorted(str(p) for p in run_dir.glob("*.csv"))
    for model, method in (("t2", "pooled"), ("t3", "pooled"), ("paper", "paper-average")):
        cal = tmp_path / f"{model}.json"
        assert main(["-q", "fit", *runs, "--model", model, "--method", method,
                     "--out", str(cal), "--no-validation"]) == 0
        assert json.loads(cal.read_text())["provenance"]["method"] == method


def test_bad_input_exits_with_a_clear_message(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("# gyrotherm-run: 1\ntime_s,temperature_c,rate_x_dps\n0,20,1\n0,20,1\n")
    assert main(["-q", "fit", str(bad), "--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: line 4: time_s not increasing (0 then 0)" in err
    assert not (tmp_path / "c.json").exists()
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    assert main(["-q", "evaluate", str(cal), str(bad)]) == 2
    assert "missing field 'schema'" in capsys.readouterr().err


def test_paper_tables(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["-q", "paper", "--rate-hz", "1", "--axis", "y"]) == 0
    out = capsys.readouterr().out
    assert "Table 1" in out and "mean (eq. 12)" in out and "Table 2" in out
    assert "paper (eq.12)" in out and "t2 60 min" in out


def test_fit_a_single_run(run_dir: Path, tmp_path: Path) -> None:
    one = str(sorted(run_dir.glob("*.csv"))[0])
    assert main(["-q", "fit", one, "--model", "paper", "--out", str(tmp_path / "c.json")]) == 0
    assert (tmp_path / "c.json").exists()
