"""``gyrotherm evaluate --zero``: the boot-time zero offline, on the independent
generator's runs (each with its own switch-on offset, metadata
``switch_on_offset_dps``): it measures what the calibration cannot know, checked
against the generator's truth; bad specs are refused naming the key."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, synth_runs
from gyrotherm.cli import main
from gyrotherm.codecs import write_run
from gyrotherm.compensation import features, load_calibration, removed_bias

READOUT = ["--temperature-lsb-c", "0.125", "--update-period-s", "1.28"]


def test_evaluate_zero_measures_what_the_calibration_misses(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The zero equals the generator's truth over its window: the mean of (true bias +
    the run's switch-on offset − the calibration's bias), to the window's noise
    (white 0.019 °/s per sample / √200 plus bias instability: 0.005 °/s)."""
    runs, _ = synth_runs(SynthConfig(duration_s=3000.0, rate_hz=10.0), n_runs=4, seed=101)
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv")) for r in runs]
    cal_path = tmp_path / "cal.json"
    assert main(["-q", "fit", *paths[:3], "--out", str(cal_path), "--no-validation",
                 *READOUT]) == 0
    held, cal = runs[3], load_calibration(cal_path)
    model = removed_bias(cal, features(held, cal.estimator)).bias["x"][0]
    t = held.time_s - held.time_s[0]
    slow = held.true_bias_dps["x"] + float(held.metadata["switch_on_offset_dps"])
    window = (t >= 30.0) & (t < 50.0)
    missed = float(np.mean(slow[window] - model[window]))
    assert abs(missed) > 0.015  # worth measuring on this seed
    plain, zeroed = tmp_path / "plain.json", tmp_path / "zeroed.json"
    assert main(["-q", "evaluate", str(cal_path), paths[3], "--rest", "all", "--json",
                 str(plain)]) == 0
    assert main(["-q", "evaluate", str(cal_path), paths[3], "--rest", "all", "--json",
                 str(zeroed), "--zero-options", "settle_s=30,window_s=20"]) == 0
    p, z = json.loads(plain.read_text()), json.loads(zeroed.read_text())
    assert "zero" not in p
    (zr,) = z["zero"]["runs"]
    assert z["zero"]["config"]["window_s"] == 20.0 and z["zero"]["config"]["max_std_dps"] == 0.5
    # 10 Hz from the run's first row: the window opens at 30 s and is closed by the row
    # at 50 s (one row later when t − t0 rounds below 30.0 on the run's clock)
    assert zr["status"] == "done" and zr["windows_rejected"] == 0
    assert zr["done_s"] - held.time_s[0] == pytest.approx(50.05, abs=0.06)
    assert zr["offset_dps"]["x"] == pytest.approx(missed, abs=0.005)
    # the scores use it: the compensated mean moves by z × (rows after the zero) / rows
    shift = p["scores"][0]["compensated"]["mean_dps"] - z["scores"][0]["compensated"]["mean_dps"]
    after = float(np.mean(t >= zr["done_s"] - held.time_s[0] - 1e-9))
    assert shift == pytest.approx(zr["offset_dps"]["x"] * after, rel=1e-6)
    # --report draws and scores the same bias (with the zero) as the printed scores
    report, rep_json = tmp_path / "report", tmp_path / "rep.json"
    assert main(["-q", "evaluate", str(cal_path), paths[3], "--rest", "all", "--json",
                 str(rep_json), "--zero-options", "settle_s=30,window_s=20", "--report",
                 str(report)]) == 0
    md = (report / "report.md").read_text(encoding="utf-8")
    rms = json.loads(rep_json.read_text())["scores"][0]["compensated"]["rms_dps"]
    assert "includes the boot-time zero" in md and f"| {rms:.4g} |" in md
    capsys.readouterr()
    # --zero before the runs: a flag, so it takes no run for its settings
    assert main(["-q", "evaluate", str(cal_path), "--zero", paths[3], "--rest", "all"]) == 0
    assert "boot-time zero, synth-101-3: done at" in capsys.readouterr().out


@pytest.mark.parametrize(("spec", "message"), [
    ("window_s=abc", "--zero-options: 'window_s=abc' is not KEY=NUMBER (keys: window_s, "
                     "settle_s"),
    ("window=5", "--zero-options: unknown key(s) ['window']"),
    ("window_s=0.1", "zero.window_s = 0.1 is outside [1, 3600]"),
])
def test_bad_zero_spec_is_named(spec: str, message: str, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    runs, _ = synth_runs(SynthConfig(duration_s=600.0, rate_hz=5.0), n_runs=2, seed=3)
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv")) for r in runs]
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", paths[0], "--out", str(cal), "--no-validation", *READOUT]) == 0
    assert main(["-q", "evaluate", str(cal), paths[1], "--zero-options", spec]) == 2
    assert message in capsys.readouterr().err
