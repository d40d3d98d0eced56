"""``gyrotherm diagnose``, ``fit`` and ``evaluate`` on candump logs (recognised by content).

The logs are runs of the independent synthetic generator (a hidden warm-up:
time since power-on matters) encoded frame by frame by
:func:`gyrotherm.sim.frames_from_run` at wall-clock timestamps, as a logger
on a bus would record them.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, synth_runs
from gyrotherm.analysis.synth._synth import SynthTruth
from gyrotherm.cli import main
from gyrotherm.codecs import FrameEncoder, Run, write_candump, write_run
from gyrotherm.sim import frames_from_run

WALL_CLOCK_S = 1_763_000_000.0


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Path], list[Run], SynthTruth]:
    out = tmp_path_factory.mktemp("logs")
    cfg = replace(SynthConfig(duration_s=6000.0, rate_hz=10.0), effects={"warmup": {}})
    runs, truth = synth_runs(cfg, n_runs=4, seed=101)
    paths = []
    for i, run in enumerate(runs):
        # no extension: the CLI must recognise the log by its content
        path = out / f"bus-{i}"
        frames = frames_from_run(run, encoder=FrameEncoder(), t0_s=WALL_CLOCK_S + i,
                                 temperature_period_s=0.0)  # a temperature frame per row
        write_candump(path, frames)
        paths.append(path)
    # a bit flipped on the bus: one rate frame of run 1 fails its CRC
    lines = paths[1].read_text().splitlines()
    head, data = lines[101].split("#")
    assert head.endswith(" 120")
    lines[101] = f"{head}#{int(data[0], 16) ^ 8:X}{data[1:]}"
    paths[1].write_text("\n".join(lines) + "\n")
    return paths, runs, truth


def test_diagnose_finds_a_hidden_warmup_in_candump_logs(
        logged: tuple[list[Path], list[Run], SynthTruth], tmp_path: Path) -> None:
    paths, _, truth = logged
    out = tmp_path / "d.json"
    assert main(["-q", "diagnose", *map(str, paths), "--json", str(out),
                 "--no-simulation"]) == 0
    data = json.loads(out.read_text())
    assert data["runs"] == [p.name for p in paths]
    assert [f["effect"] for f in data["findings"]] == ["warmup"]
    params = data["findings"][0]["params"]
    injected = truth.effects["warmup"]
    # the wall-clock stamps were replaced by time since the first frame (= power-on):
    # the transient's time constant and amplitude come out right
    assert params["tau_s"] == pytest.approx(injected["tau_s"], rel=0.3)
    assert params["amplitude_dps"] == pytest.approx(injected["amplitude_dps"], rel=0.3)
    assert data["extended"]["gain"] > 1.1
    # the lost frame is reported, not dropped silently
    assert data["notes"][-1] == (f"bus-1: candump log {paths[1]} (120002 frames): "
                                 "crc_mismatch: 1, counter_jumps: 1")


def _quantised(run: Run) -> Run:
    """``run`` on the DBC's grid (round half to even, as the encoder rounds)."""
    rates = {"x": np.round(run.rates_dps["x"] / 0.002) * 0.002}
    return replace(run, temperature_c=np.round(run.temperature_c / 0.01) * 0.01,
                   rates_dps=rates)


def test_fit_and_evaluate_read_candump_logs_like_run_files(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    runs, _ = synth_runs(SynthConfig(duration_s=1200.0, rate_hz=5.0), n_runs=3, seed=7)
    logs = []
    for i, run in enumerate(runs):
        path = tmp_path / f"bus-{i}.txt"
        write_candump(path, frames_from_run(run, encoder=FrameEncoder(), t0_s=WALL_CLOCK_S,
                                            temperature_period_s=0.0))
        logs.append(str(path))
    csvs = [str(write_run(_quantised(r), tmp_path / f"{r.name}.csv")) for r in runs[:2]]
    cal_log, cal_csv = tmp_path / "log.json", tmp_path / "csv.json"
    assert main(["-q", "fit", *logs[:2], "--out", str(cal_log), "--no-validation"]) == 0
    assert main(["-q", "fit", *csvs, "--out", str(cal_csv), "--no-validation"]) == 0
    a, b = (json.loads(p.read_text()) for p in (cal_log, cal_csv))
    assert list(a["coefficients"]) == list(b["coefficients"]) == ["x"]  # y, z: zero-filled
    assert [r["name"] for r in a["provenance"]["runs"]] == ["bus-0", "bus-1"]
    # the same data, up to the log's microsecond timestamps: the same fit
    assert a["coefficients"]["x"] == pytest.approx(b["coefficients"]["x"], rel=1e-4, abs=1e-6)
    capsys.readouterr()
    assert main(["-q", "evaluate", str(cal_log), logs[2], "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (score,) = doc["scores"]
    assert score["axis"] == "x" and score["run"] == "bus-2"
    assert score["compensated"]["rms_dps"] < 0.75 * score["raw"]["rms_dps"]  # 0.54 here
