"""``gyrotherm learn``: a calibration from power-ons at rest, end to end on simulated power-on
logs (truth known), the refusals that say why, and a real PX4 log it cannot learn from."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import features, load_calibration
from gyrotherm.compensation._learn import warmup_rows
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim._life import LIFE_GYRO, life, power_on

DATA = Path(__file__).resolve().parents[1] / "data"
TAU = str(LIFE_GYRO.tau_s)


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    out = tmp_path_factory.mktemp("life")
    runs = [*life(6, seed=21), power_on(8.0, warmup_s=200.0, motion_s=400.0, seed=77,
                                        name="drives-off")]
    return [write_run(r, out / f"{r.name}.csv") for r in runs]


def test_learns_adopts_and_writes_with_provenance(
    logs: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    out, report = tmp_path / "learnt.json", tmp_path / "learn.json"
    assert main(["-q", "learn", *map(str, logs), "--out", str(out), "--tau-s", TAU,
                 "--json", str(report)]) == 0
    doc = json.loads(report.read_text())
    assert doc["decision"]["adopt"] is True and doc["calibration"] == str(out)
    assert [w["run"] for w in doc["warmups"]][-1] == "drives-off"
    drive = doc["warmups"][-1]
    assert drive["rows"] < 200 * 10  # the rows after it drove off are not learnt
    cal = load_calibration(out)
    assert len(cal.provenance["power_ons"]) == 7
    assert cal.provenance["validation"]["adopt"] is True
    # against the simulator's truth on a power-on it never saw
    est = EstimatorConfig(tau_s=LIFE_GYRO.tau_s)
    f = features(power_on(15.0, seed=4242), est)
    use = warmup_rows(f)
    for a in ("x", "y", "z"):
        err = (cal.bias_series(a, f.temperature_c, f.delta_t_c)[0] - f.true_bias_dps[a])[use]
        assert np.std(err) < 0.15 * np.std(f.true_bias_dps[a][use])
    assert capsys.readouterr().out == ""


def test_too_few_warmups_is_exit_2_with_the_gate(logs: list[Path], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "none.json"
    assert main(["learn", str(logs[0]), str(logs[1]), "--out", str(out), "--tau-s", TAU]) == 2
    said = capsys.readouterr().out
    assert "warm-ups: 2 at rest, at least 3 needed" in said
    assert "nothing adopted" in said and not out.exists()


def test_a_log_that_misses_its_power_on_is_left_out_and_named(
    logs: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    late: Run = power_on(20.0, seed=31, name="late")
    late = replace(late, time_s=late.time_s + 300.0)  # logging began 300 s after boot
    path = write_run(late, tmp_path / "late.csv")
    assert main(["learn", *map(str, logs[:4]), str(path), "--out", str(tmp_path / "c.json"),
                 "--tau-s", TAU]) == 0
    err = capsys.readouterr().err
    assert "late.csv: late: the log starts 300 s after power-on" in err
    assert "SDLOG_MODE = 1 or 2" in err


def test_a_better_current_calibration_is_kept(logs: list[Path], tmp_path: Path) -> None:
    first = tmp_path / "first.json"
    assert main(["-q", "learn", *map(str, logs), "--out", str(first), "--tau-s", TAU]) == 0
    again = tmp_path / "again.json"
    # three warm-ups cannot beat what seven gave, on those three
    assert main(["-q", "learn", *map(str, logs[:3]), "--out", str(again),
                 "--current", str(first)]) == 2
    assert not again.exists()


def test_real_px4_log_logged_at_1_hz_is_refused_with_the_logger_setting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    log = DATA / "px4_sample_log_small_imu.ulg"  # a Cube Orange's 3 IMUs (tests/data)
    assert main(["learn", str(log), "--out", str(tmp_path / "c.json")]) == 2
    assert "learn learns one IMU: these logs hold 3" in capsys.readouterr().err
    assert main(["learn", str(log), "--device", "2424842",
                 "--out", str(tmp_path / "c.json")]) == 2
    said = capsys.readouterr()
    assert "SDLOG_PROFILE 'thermal calibration'" in said.err
    assert "warm-ups: 0 at rest" in said.out
