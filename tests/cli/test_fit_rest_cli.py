"""``gyrotherm fit --rest`` and several devices in one set of runs, end to end."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import Run, read_run, write_run
from gyrotherm.sim import BiasTruth, GyroParams, chamber_runs
from motionkit import truth_rms, with_rotations

TURNS_S = ((700.0, 730.0), (1400.0, 1460.0))
#: Device b's true bias: device a's (the simulator default) with other coefficients.
TRUTH_B = {
    "x": {"T^2": -6.0e-5, "T": 0.012, "dT": -0.040, "T*dT": 2.0e-4, "1": -0.15},
    "y": {"T^2": 9.0e-5, "T": -0.008, "dT": 0.025, "T*dT": -3.0e-4, "1": 0.25},
    "z": {"T^2": -4.0e-5, "T": 0.005, "dT": 0.020, "T*dT": 1.0e-4, "1": -0.05},
}


def _device_runs(device: str, gyro: GyroParams, seed: int) -> list[Run]:
    runs = chamber_runs([10, 40], seed=seed, rate_hz=5.0, hold_s=1200.0, gyro=gyro)
    return [replace(with_rotations(r, TURNS_S, accel=True, seed=seed + i),
                    name=f"{device}-{r.name}", metadata={**r.metadata, "device_id": device})
            for i, r in enumerate(runs)]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Path]]:
    out = tmp_path_factory.mktemp("logs")
    gyros = {"imu-a": GyroParams(), "imu-b": GyroParams(bias=BiasTruth(coefficients=TRUTH_B))}
    return {dev: [write_run(r, out / f"{r.name}.csv") for r in _device_runs(dev, g, 10 * k)]
            for k, (dev, g) in enumerate(gyros.items())}


def _truth_rms(cal_path: Path, runs: list[Path]) -> float:
    return truth_rms(cal_path, [read_run(p) for p in runs], TURNS_S)


def test_two_devices_two_calibrations_each_its_own_truth(
    logs: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    every = [str(p) for paths in logs.values() for p in paths]
    report = tmp_path / "report.json"
    out = tmp_path / "cals"
    assert main(["-q", "fit", *every, "--out", str(out), "--no-validation",
                 "--json", str(report)]) == 0
    printed = capsys.readouterr()
    assert printed.out == ""  # --json replaces the tables; the rest report goes to stderr
    assert "Rest detection" in printed.err
    doc = json.loads(report.read_text())
    assert [(c["device"], len(c["runs"])) for c in doc["calibrations"]] == [("imu-a", 2),
                                                                            ("imu-b", 2)]
    assert [c["path"] for c in doc["calibrations"]] == [str(out / "imu-a.json"),
                                                        str(out / "imu-b.json")]
    for run in doc["rest"]["runs"]:
        assert len(run["segments"]) == len(TURNS_S)
        assert 90.0 < run["excluded_s"] < 90.0 + 4 * len(TURNS_S) * 2.2
    for dev in logs:
        cal = json.loads((out / f"{dev}.json").read_text())
        assert cal["provenance"]["device_id"] == dev
        assert all(r["rest_rows"] < r["rows"] for r in cal["provenance"]["runs"])
    own_a, own_b = _truth_rms(out / "imu-a.json", logs["imu-a"]), \
        _truth_rms(out / "imu-b.json", logs["imu-b"])
    cross = _truth_rms(out / "imu-a.json", logs["imu-b"])
    assert own_a < 0.02 and own_b < 0.02
    assert cross > 10 * max(own_a, own_b)


def test_motion_kept_biases_the_fit(logs: dict[str, list[Path]], tmp_path: Path) -> None:
    runs = [str(p) for p in logs["imu-a"]]
    for mode in ("auto", "all"):
        assert main(["-q", "fit", *runs, "--out", str(tmp_path / f"{mode}.json"),
                     "--no-validation", "--rest", mode]) == 0
    masked = _truth_rms(tmp_path / "auto.json", logs["imu-a"])
    kept = _truth_rms(tmp_path / "all.json", logs["imu-a"])
    assert kept > 10 * masked


def test_chamber_runs_fit_identically_with_and_without_detection(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv"))
             for r in chamber_runs([5, 30], seed=4, rate_hz=2.0, hold_s=900.0)]
    for mode in ("auto", "all"):
        assert main(["-q", "fit", *paths, "--out", str(tmp_path / f"{mode}.json"),
                     "--no-validation", "--rest", mode]) == 0
        said = capsys.readouterr().out
        assert ("Rest detection: every row at rest (2 runs)" in said) == (mode == "auto")
    auto = json.loads((tmp_path / "auto.json").read_text())
    every = json.loads((tmp_path / "all.json").read_text())
    for key in ("coefficients", "scaling", "range"):
        assert auto[key] == every[key]
    assert "rest_rows" not in json.dumps(auto["provenance"]["runs"])


def test_several_devices_into_one_json_file_is_refused(
    logs: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    every = [str(p) for paths in logs.values() for p in paths]
    assert main(["-q", "fit", *every, "--out", str(tmp_path / "cal.json"),
                 "--no-validation"]) == 2
    assert "give a directory or a name with {device}" in capsys.readouterr().err
    assert main(["-q", "fit", *every, "--out", str(tmp_path / "cal-{device}.json"),
                 "--no-validation", "--rest", "all"]) == 0
    assert (tmp_path / "cal-imu-a.json").exists() and (tmp_path / "cal-imu-b.json").exists()


def test_export_of_a_device_fits_its_cubic_at_rest(
    logs: dict[str, list[Path]], tmp_path: Path,
) -> None:
    runs = [str(p) for p in logs["imu-b"]]
    cal = tmp_path / "cal-{device}.json"
    assert main(["-q", "fit", *runs, "--out", str(cal), "--no-validation"]) == 0
    docs = {}
    for mode in ("auto", "all"):
        doc = tmp_path / f"{mode}.json"
        assert main(["-q", "export", str(tmp_path / "cal-imu-b.json"), "--rest", mode,
                     "--cubic-target", "rows",  # the rows' cubic: what --rest acts on
                     "--ardupilot", str(tmp_path / f"{mode}.param"), "--json", str(doc)]) == 0
        docs[mode] = json.loads(doc.read_text())
    # each exported cubic, applied to the rows truly at rest (outside the turns ± 2 s)
    rms = {}
    for mode, doc in docs.items():
        c = doc["cubic"]
        resid = []
        for p in logs["imu-b"]:
            run = read_run(p)
            still = np.ones(len(run), dtype=bool)
            for a, b in TURNS_S:
                still &= ~((run.time_s >= a - 2) & (run.time_s < b + 2))
            u = np.clip(run.temperature_c, c["t_min_c"], c["t_max_c"]) - c["t_ref_c"]
            cubic = np.polyval(c["coefficients_rad_s"]["x"][::-1], u)
            resid.append((run.rates_dps["x"] - np.degrees(cubic))[still])
        rms[mode] = float(np.sqrt(np.mean(np.concatenate(resid) ** 2)))
    auto_x = docs["auto"]["validation"]["axes"]["x"]
    assert rms["auto"] == pytest.approx(auto_x["cubic_rms_dps"], rel=0.05)
    assert rms["auto"] < 0.5 * auto_x["raw_rms_dps"]
    assert rms["all"] > 3 * rms["auto"]  # fitted through the turns: pulled off


def _x_scores(doc: dict[str, object]) -> dict[str, dict[str, float]]:
    scores = doc["scores"]
    assert isinstance(scores, list)
    return {s["run"]: s["compensated"] for s in scores if s["axis"] == "x"}


def test_evaluate_scores_the_rest_rows_like_the_same_runs_without_motion(
    logs: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """Independent truth: the same simulated runs before the turns were added
    (``_device_runs`` without ``with_rotations``), scored whole."""
    moving = [str(p) for p in logs["imu-a"]]
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *moving, "--out", str(cal), "--no-validation"]) == 0
    still = [write_run(replace(r, name=f"imu-a-{r.name}"), tmp_path / f"{r.name}.csv")
             for r in chamber_runs([10, 40], seed=0, rate_hz=5.0, hold_s=1200.0)]
    docs = {}
    for label, runs, mode in (("auto", moving, "auto"), ("all", moving, "all"),
                              ("still", [str(p) for p in still], "all")):
        out = tmp_path / f"{label}.json"
        assert main(["-q", "evaluate", str(cal), *runs, "--rest", mode,
                     "--json", str(out)]) == 0
        docs[label] = json.loads(out.read_text())
    assert "Rest detection (rows excluded from the scores)" in capsys.readouterr().err
    for run in docs["auto"]["rest"]["runs"]:
        assert len(run["segments"]) == len(TURNS_S)
    assert docs["all"]["rest"] == {"mode": "all", "runs": []}
    auto, every, truth = (_x_scores(docs[k]) for k in ("auto", "all", "still"))
    assert auto.keys() == truth.keys() == every.keys()
    for name, score in truth.items():
        excluded = next(r["excluded_rows"] for r in docs["auto"]["rest"]["runs"]
                        if r["run"] == name)
        assert auto[name]["n"] == score["n"] - excluded
        assert auto[name]["rms_dps"] == pytest.approx(score["rms_dps"], rel=0.05)
        assert every[name]["rms_dps"] > 20 * score["rms_dps"]  # the turns, scored


def test_diagnose_refuses_motion_and_names_it(
    logs: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    runs = [str(p) for p in logs["imu-a"]]
    out = tmp_path / "d.json"
    assert main(["-q", "diagnose", *runs, "--no-simulation", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "rest detection left rows out of 2 of 2 runs" in err
    for name in ("imu-a-heat-10min", "imu-a-heat-40min"):
        assert f"{name}: 2 segments not at rest (69" in err  # the turns start at 700 s
    assert "rate above 5 °/s" in err  # the reasons, as fit prints them
    assert "--rest all" in err and not out.exists()


def test_fit_effects_refuses_motion_with_the_same_message(
    logs: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    runs = [str(p) for p in logs["imu-a"]]
    assert main(["-q", "fit", *runs, "--out", str(tmp_path / "c.json"), "--effects",
                 "warmup"]) == 2
    err = capsys.readouterr().err
    assert "fit --effects needs the gyro at rest" in err
    assert "imu-a-heat-10min: 2 segments not at rest (69" in err
    assert not (tmp_path / "c.json").exists()


def test_runs_too_short_for_detection_are_used_whole_and_said_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """A 6-row run (detection needs 10) is scored on every row, with a note; the
    score equals the one with --rest all."""
    (run,) = chamber_runs([5], seed=2, rate_hz=1.0, hold_s=600.0)
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", str(write_run(run, tmp_path / "long.csv")), "--out", str(cal),
                 "--no-validation", "--model", "t2"]) == 0
    short = write_run(run.slice(0, 6), tmp_path / "short.csv")
    docs = {}
    for mode in ("auto", "all"):
        out = tmp_path / f"{mode}.json"
        assert main(["-q", "evaluate", str(cal), str(short), "--rest", mode,
                     "--json", str(out)]) == 0
        docs[mode] = json.loads(out.read_text())
    (rep,) = docs["auto"]["rest"]["runs"]
    assert rep["note"] == "6 rows, too few for rest detection (at least 10): every row used"
    said = capsys.readouterr().err
    assert "Rest detection: heat-05min: 6 rows, too few for rest detection" in said
    assert "every row at rest" not in said  # nothing was detected, nothing claimed
    assert docs["auto"]["scores"] == docs["all"]["scores"]
    assert all(s["compensated"]["n"] == 6 for s in docs["auto"]["scores"])
