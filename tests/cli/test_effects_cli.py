"""Extended models end to end through the CLI: ``fit --effects`` recovers an effect
injected by the independent generator (``analysis.synth._synth``, not gyrotherm's
simulator) and the version-2 calibration beats the paper one on a held-out run
under ``evaluate``; ``diagnose --calibration`` writes a complete calibration."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, synth_runs
from gyrotherm.cli import main
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import load_calibration

#: the readout the generator uses (0.125 °C every 1.28 s), told to the estimator
READOUT = ["--temperature-lsb-c", "0.125", "--update-period-s", "1.28"]
FAST = SynthConfig(duration_s=6000.0, rate_hz=10.0)
#: the diagnosis tests' tolerance and checked parameters (tests/analysis/test_diagnose.py)
CHECKED = {"warmup": ("amplitude_dps", "tau_s"), "hysteresis": ("amplitude_dps",)}


def _write(runs: list[Run], folder: Path) -> list[str]:
    folder.mkdir(parents=True, exist_ok=True)
    return [str(write_run(r, folder / f"{r.name}.csv")) for r in runs]


@pytest.mark.parametrize(("effect", "seed"), [("warmup", 101), ("hysteresis", 207)])
def test_fit_effects_recovers_and_beats_paper_on_a_held_out_run(
    effect: str, seed: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs, truth = synth_runs(replace(FAST, effects={effect: {}}), n_runs=5, seed=seed)
    paths = _write(runs, tmp_path / "runs")
    train, held = paths[:4], paths[4]
    paper, extended = tmp_path / "paper.json", tmp_path / "ext.json"
    assert main(["-q", "fit", *train, "--out", str(paper), "--no-validation", *READOUT]) == 0
    assert main(["-q", "fit", *train, "--effects", effect, "--out", str(extended),
                 *READOUT]) == 0
    out = capsys.readouterr().out
    assert f"{effect}:" in out and "(paper) →" in out
    cal = load_calibration(extended)
    assert cal.version == 2 and cal.effect_names("x") == (effect,)
    params = cal.effects_of("x").to_params()[effect]
    for key in CHECKED[effect]:
        assert params[key] == pytest.approx(truth.effects[effect][key], rel=0.3), key
    doc = json.loads(extended.read_text())
    assert doc["provenance"]["effects_requested"] == [effect]
    assert doc["provenance"]["effects_fit"]["x"]["gain"] > 1.1

    def rms(path: Path) -> tuple[float, float]:
        assert main(["-q", "evaluate", str(path), held, "--json"]) == 0
        score = json.loads(capsys.readouterr().out)["scores"][0]
        return score["compensated"]["rms_dps"], score["truth"]["rms_dps"]

    paper_rms, paper_truth = rms(paper)
    ext_rms, ext_truth = rms(extended)
    assert ext_rms < 0.9 * paper_rms and ext_truth < 0.8 * paper_truth
    assert main(["-q", "evaluate", str(extended), held]) == 0
    assert "runtime state starts there" in capsys.readouterr().out


def test_fit_effects_refuses_unknown_names_and_other_models(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # checked before any run file is read (a.csv does not exist)
    out = str(tmp_path / "c.json")
    assert main(["-q", "fit", "a.csv", "--effects", "creep", "--out", out]) == 2
    assert "--effects 'creep': unknown ['creep']; known: thermal_lag," in capsys.readouterr().err
    assert main(["-q", "fit", "a.csv", "--effects", "drift", "--model", "t3", "--out", out]) == 2
    assert "not --model t3 --method auto" in capsys.readouterr().err
    assert not Path(out).exists()


def test_diagnose_calibration_on_null_data_is_the_paper_model_on_every_axis(
    tmp_path: Path,
) -> None:
    runs, _ = synth_runs(replace(FAST, duration_s=3000.0), n_runs=3, seed=3)
    # a second axis: the same device's rate with another seed's noise (no effect either)
    other, _ = synth_runs(replace(FAST, duration_s=3000.0), n_runs=3, seed=4)
    runs = [replace(r, rates_dps={"x": r.rates_dps["x"],
                                  "y": o.rates_dps["x"][: len(r)]})
            for r, o in zip(runs, other, strict=True)]
    assert all(len(r.rates_dps["y"]) == len(r) for r in runs)
    paths = _write(runs, tmp_path / "runs")
    cal_path = tmp_path / "cal.json"
    assert main(["-q", "diagnose", *paths, "--json", str(tmp_path / "d.json"),
                 "--no-simulation", "--calibration", str(cal_path)]) == 0
    cal = load_calibration(cal_path)
    assert cal.version == 1 and cal.model.name == "paper" and cal.axes == ("x", "y")
    doc = json.loads(cal_path.read_text())
    assert "effects" not in doc
    prov = doc["provenance"]["diagnosis"]
    assert prov["axis"] == "x" and prov["axes"]["x"]["selected_by"] == "diagnosis"
    assert prov["axes"]["y"] == {**prov["axes"]["y"], "effects": [],
                                 "selected_by": "forward selection"}
    assert [r["sha256"] for r in prov["runs"]] == [
        hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths]
    # τ regressed from the logged chamber (the generator's case: 80–250 s), stored
    assert prov["tau_from_chamber"] and cal.estimator.tau_s == prov["tau_s"]
    assert 60.0 < cal.estimator.tau_s < 300.0
    assert np.isfinite(cal.bias_at(20.0, 0.0).bias_dps["y"])
