"""``fit``, ``evaluate``, ``diagnose`` and ``import`` on the user's own files: logger
CSVs (µs, rad/s; written here with the csv module from a known bias law) and a
candump log of a gyro with its own DBC."""

from __future__ import annotations

import csv
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import read_run
from gyrotherm.readers import InputSpec, read_runs
from userdatakit import bus_log, logger_csv
from userdbckit import user_log

COLUMNS = ["--columns", "time=timestamp:us", "temperature=temp:degC", "x=gx:rad/s",
           "y=gy:rad/s", "z=gz:rad/s"]
def test_fit_and_evaluate_logger_csvs(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      ) -> None:
    train = [str(logger_csv(tmp_path / f"log-{i}.csv", top_c=top, seed=i))
             for i, top in enumerate((45.0, 60.0))]
    held = str(logger_csv(tmp_path / "log-held.csv", top_c=55.0, seed=9))
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *train, "--out", str(cal), "--model", "t2",
                 "--no-validation", *COLUMNS]) == 0
    doc = json.loads(cal.read_text())
    assert [r["name"] for r in doc["provenance"]["runs"]] == ["log-0", "log-1"]
    capsys.readouterr()
    assert main(["-q", "evaluate", str(cal), held, "--json", *COLUMNS]) == 0
    scores = json.loads(capsys.readouterr().out)["scores"]
    assert [s["axis"] for s in scores] == ["x", "y", "z"]
    for s in scores:
        # the law is recovered: only the 0.002 °/s noise (and estimator lag) remains
        assert s["compensated"]["rms_dps"] < 0.01
        assert s["raw"]["rms_dps"] > 0.05


def test_fit_without_columns_explains(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      ) -> None:
    path = logger_csv(tmp_path / "log.csv", top_c=40.0, seed=1, rows=10)
    assert main(["-q", "fit", str(path), "--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert f"gyrotherm: error: {path}: line 1: cannot tell which columns" in err
    assert "--columns time=timestamp:<s|ms|us|ns> temperature=temp:" in err


def test_import_writes_run_files_with_provenance(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    src = logger_csv(tmp_path / "log.csv", top_c=40.0, seed=3, rows=20)
    out = tmp_path / "deep" / "imported.csv"
    assert main(["-q", "import", str(src), "--out", str(out), *COLUMNS]) == 0
    run = read_run(out)
    with src.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    np.testing.assert_allclose(run.time_s, [int(r["timestamp"]) / 1e6 for r in rows])
    np.testing.assert_allclose(run.temperature_c, [float(r["temp"]) for r in rows])
    np.testing.assert_allclose(run.rates_dps["y"],
                               [math.degrees(float(r["gy"])) for r in rows], rtol=1e-8)
    md = run.metadata
    assert md["source_file"] == str(src)
    assert md["source_sha256"] == hashlib.sha256(src.read_bytes()).hexdigest()
    assert md["source_format"] == "text"
    assert md["columns"] == " ".join(COLUMNS[1:])
    assert (md["unit_time"], md["unit_temperature"], md["unit_x"]) == ("us", "degC", "rad/s")
    assert run.name == "log"
    (again,) = read_runs(out, spec=InputSpec())  # read back: a run file, imported from text
    assert (again.metadata["format"], again.metadata["source_format"]) == ("run", "text")


def test_import_several_devices_into_a_directory(tmp_path: Path) -> None:
    src = tmp_path / "two.csv"
    src.write_text("t;dev;temp;gx\n0;a;20;1\n0.5;b;30;2\n1;a;21;3\n1.5;b;31;4\n",
                   encoding="utf-8")
    cols = ["--columns", "time=t:s", "temperature=temp:degC", "x=gx:dps", "device=dev"]
    assert main(["-q", "import", str(src), "--out", str(tmp_path / "one.csv"), *cols]) == 2
    assert main(["-q", "import", str(src), "--out", str(tmp_path / "runs"), *cols]) == 0
    a, b = (read_run(tmp_path / "runs" / f"two-{d}.csv") for d in "ab")
    assert (a.name, a.metadata["device_id"], b.metadata["device_id"]) == ("two:a", "a", "b")
    np.testing.assert_array_equal(b.temperature_c, [30.0, 31.0])
    np.testing.assert_array_equal(a.rates_dps["x"], [1.0, 3.0])


def test_import_json_lists_what_was_written(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "two.csv"
    src.write_text("t;dev;temp;gx\n0;a;20;1\n0.5;b;30;2\n1;a;21;3\n1.5;b;31;4\n",
                   encoding="utf-8")
    cols = ["--columns", "time=t:s", "temperature=temp:degC", "x=gx:dps", "device=dev"]
    assert main(["-q", "import", str(src), "--out", str(tmp_path / "runs"), *cols,
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)  # the whole stdout is the JSON
    assert [(w["path"], w["run"], w["rows"], w["device_id"], w["temperature_c"])
            for w in doc["written"]] == [
        (str(tmp_path / "runs" / "two-a.csv"), "two:a", 2, "a", [20.0, 21.0]),
        (str(tmp_path / "runs" / "two-b.csv"), "two:b", 2, "b", [30.0, 31.0])]
    assert all(w["axes"] == ["x"] and w["source"] == str(src) for w in doc["written"])
    assert main(["-q", "import", str(src), "--out", str(tmp_path / "again"), *cols,
                 "--json", str(tmp_path / "runs" / "two-a.csv")]) == 2  # never over a run
    assert read_run(tmp_path / "runs" / "two-a.csv").name == "two:a"
    capsys.readouterr()
    # nor over a run file this very import is about to write: refused before writing
    assert main(["-q", "import", str(src), "--out", str(tmp_path / "new"), *cols,
                 "--json", str(tmp_path / "new" / "two-b.csv")]) == 2
    assert "one of the run files this import writes" in capsys.readouterr().err
    assert not list((tmp_path / "new").glob("*.csv"))  # nothing written


def test_import_and_fit_candump_with_user_dbc(tmp_path: Path) -> None:
    log, dbc, signals = user_log(tmp_path)
    can = ["--dbc", str(dbc), "--signals", str(signals)]
    assert main(["-q", "import", str(log), "--out", str(tmp_path / "out"), *can]) == 0
    run = read_run(tmp_path / "out" / "imu.csv")
    np.testing.assert_allclose(run.rates_dps["z"], [2.0, 1.99, 2.01], atol=1e-9)
    assert run.metadata["device_id"] == "can:0x3A0"
    assert run.metadata["source_format"] == "candump"


def test_fit_and_evaluate_candump_with_user_dbc(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    train, dbc, signals = bus_log(tmp_path / "a", 60.0)
    held, _, _ = bus_log(tmp_path / "b", 50.0)
    can = ["--dbc", str(dbc), "--signals", str(signals)]
    cal = str(tmp_path / "c.json")
    assert main(["-q", "fit", str(train), "--out", cal, "--model", "t2", *can]) == 0
    capsys.readouterr()
    assert main(["-q", "evaluate", cal, str(held), "--json", *can]) == 0
    for s in json.loads(capsys.readouterr().out)["scores"]:
        assert s["compensated"]["rms_dps"] < 0.01 < 0.05 < s["raw"]["rms_dps"]
    # without the user's DBC the log is refused, naming the shipped message
    assert main(["-q", "fit", str(train), "--out", cal]) == 2
    assert "no valid rate frame (message 'GyroRate', id 0x120)" in capsys.readouterr().err


def test_diagnose_reads_logger_csvs(tmp_path: Path) -> None:
    paths = [str(logger_csv(tmp_path / f"log-{i}.csv", top_c=top, seed=i, rows=900))
             for i, top in enumerate((45.0, 60.0, 52.0))]
    out = tmp_path / "d.json"
    assert main(["-q", "diagnose", *paths, "--json", str(out), "--no-simulation",
                 *COLUMNS]) == 0
    data = json.loads(out.read_text())
    assert data["runs"] == ["log-0", "log-1", "log-2"]
