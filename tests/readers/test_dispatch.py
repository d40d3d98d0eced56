"""read_runs' dispatch, and candump logs of a gyro with its own DBC and signal map
(frames encoded by cantools' own encoder, log lines written here)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.codecs import Run, SignalMap, write_run
from gyrotherm.readers import InputSpec, detect_format, load_signal_map, read_runs
from userdbckit import SIGNALS_TOML, user_log


def test_candump_with_user_dbc_and_signal_map(tmp_path: Path) -> None:
    log, dbc, signals = user_log(tmp_path)
    spec = InputSpec(dbc=dbc, signals=load_signal_map(signals))
    (run,) = read_runs(log, spec=spec)
    np.testing.assert_allclose(run.time_s, [0.6, 1.0, 1.6])
    # the latest temperature at or before each rate sample
    np.testing.assert_allclose(run.temperature_c, [30.0, 30.0, 30.5078125])
    np.testing.assert_allclose(run.rates_dps["x"], [0.25, 0.3, 0.26], atol=1e-12)
    np.testing.assert_allclose(run.rates_dps["y"], [-1.5, -1.49, -1.51], atol=1e-12)
    np.testing.assert_allclose(run.rates_dps["z"], [2.0, 1.99, 2.01], atol=1e-12)
    assert run.metadata["format"] == "candump"
    assert run.metadata["device_id"] == "can:0x3A0"
    assert run.metadata["dbc"] == "imu.dbc"


def test_candump_of_a_foreign_gyro_fails_with_the_shipped_dbc(tmp_path: Path) -> None:
    log, _, _ = user_log(tmp_path)
    with pytest.raises(RunFileError, match=r"no valid rate frame \(message 'GyroRate', "
                       r"id 0x120\) among 5 frames \(rejected unknown_id: 5\)"):
        read_runs(log, spec=InputSpec())


def test_signal_map_file_forms_and_errors(tmp_path: Path) -> None:
    plain = tmp_path / "plain.toml"
    body = SIGNALS_TOML.split("[can.signals]\n", 1)[1]
    plain.write_text(body, encoding="utf-8")
    assert load_signal_map(plain).rate_message == "ImuAngularRate"
    daemon = tmp_path / "gyrotherm.toml"  # a daemon config without [can.signals]
    daemon.write_text('vehicle = "v"\n[can]\ninterface = "virtual"\n', encoding="utf-8")
    assert load_signal_map(daemon) == SignalMap.default()
    bad = tmp_path / "bad.toml"
    bad.write_text(body.replace("rate_x_signal", "rate_q_signal"), encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"{bad}: unknown key\(s\) \['rate_q_signal'\]"):
        load_signal_map(bad)
    with pytest.raises(ConfigError, match="cannot read signal map"):
        load_signal_map(tmp_path / "absent.toml")


def test_detect_format(tmp_path: Path) -> None:
    run = Run(name="r", time_s=np.array([0.0, 1.0]), temperature_c=np.array([20.0, 21.0]),
              rates_dps={"x": np.array([0.0, 0.1])})
    write_run(run, tmp_path / "run.csv")
    user_log(tmp_path)
    (tmp_path / "text.csv").write_text("t,c,g\n0,1,2\n", encoding="utf-8")
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n", encoding="utf-8")
    (tmp_path / "empty-dir").mkdir()
    want = {"run.csv": "run", "imu.log": "candump", "text.csv": "text", "f.ulg": "ulog",
            "f.BIN": "dataflash", "f.mcap": "rosbag", "f.db3": "rosbag", "bag": "rosbag"}
    for name, fmt in want.items():
        assert detect_format(tmp_path / name) == fmt, name
    with pytest.raises(RunFileError, match="not a rosbag2 one"):
        detect_format(tmp_path / "empty-dir")
    (read,) = read_runs(tmp_path / "run.csv", spec=InputSpec())
    assert (read.metadata["format"], read.metadata["device_id"]) == ("run", "")
    # a run file saved with a BOM by an editor: read as text with the run-file columns
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + (tmp_path / "run.csv").read_bytes())
    (again,) = read_runs(bom, spec=InputSpec())
    assert again.metadata["format"] == "text"
    np.testing.assert_array_equal(again.rates_dps["x"], read.rates_dps["x"])
    np.testing.assert_array_equal(again.time_s, read.time_s)


def test_missing_reader_module_and_unknown_format(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "flight.ulg"
    path.write_bytes(b"ULog\x01\x12\x35")
    monkeypatch.setitem(sys.modules, "gyrotherm.readers._ulog", None)
    with pytest.raises(RunFileError, match=rf"{path}: format 'ulog': this gyrotherm has no "
                       r"ulog reader \(module gyrotherm.readers._ulog is missing\)"):
        read_runs(path, spec=InputSpec())
    with pytest.raises(RunFileError, match="unknown format 'xls'; known: auto, run, text"):
        read_runs(path, spec=InputSpec(format="xls"))
    with pytest.raises(RunFileError, match="no such file"):
        read_runs(tmp_path / "absent.csv", spec=InputSpec(format="text"))


def test_detect_format_by_content_not_name(tmp_path: Path) -> None:
    """Each format's magic bytes decide, whatever the file is called; an empty file goes
    by its suffix (so the error names the format meant); a DataFlash text log and an
    empty file of no known suffix are refused with one line."""
    magic = {"ulog": b"ULog\x01\x12\x35\x01", "dataflash": b"\xa3\x95\x80",
             "mcap": b"\x89MCAP0\r\n", "db3": b"SQLite format 3\x00",
             "bag": b"#ROSBAG V2.0\n", "run": b"# gyrotherm-run: 1\n"}
    want = {"ulog": "ulog", "dataflash": "dataflash", "mcap": "rosbag", "db3": "rosbag",
            "bag": "rosbag", "run": "run"}
    for kind, head in magic.items():
        for name in (f"{kind}.log", f"{kind}.csv", f"{kind}.ulog", kind):
            path = tmp_path / name
            path.write_bytes(head + b"\x00" * 32)
            assert detect_format(path) == want[kind], name
    for suffix, fmt in {".ulg": "ulog", ".BIN": "dataflash", ".bag": "rosbag"}.items():
        (tmp_path / f"empty{suffix}").write_bytes(b"")
        assert detect_format(tmp_path / f"empty{suffix}") == fmt
    (tmp_path / "empty.csv").write_bytes(b"")
    with pytest.raises(RunFileError, match=r"empty.csv: the file is empty"):
        detect_format(tmp_path / "empty.csv")
    (tmp_path / "flight.log").write_text("FMT, 128, 89, FMT, BBnNZ, Type,Length,Name\n")
    with pytest.raises(RunFileError, match=r"flight.log: an ArduPilot DataFlash text log"):
        detect_format(tmp_path / "flight.log")
