"""The delimited text reader: files written here with the csv module (never by the
reader under test), values checked against hand-computed conversions."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.codecs import Run, parse_run
from gyrotherm.readers import InputSpec, parse_columns, read_runs, read_text

LOGGER_COLUMNS = "time=timestamp:us temperature=temp:degC x=gx:rad/s y=gy:rad/s z=gz:rad/s"
#: timestamp µs, temp °C, gx gy gz rad/s: rates chosen so that °/s are round numbers.
LOGGER_ROWS = [
    ("1000000", "20.5", repr(math.pi / 180), repr(-math.pi / 90), "0"),
    ("1020000", "20.75", repr(math.pi / 360), "0", repr(math.pi)),
    ("1040000", "21", "0", repr(math.pi / 18), repr(-math.pi / 4)),
]
#: The same rows by hand: s, °C, °/s.
TIME_S = [1.0, 1.02, 1.04]
TEMP_C = [20.5, 20.75, 21.0]
RATES_DPS = {"x": [1.0, 0.5, 0.0], "y": [-2.0, 0.0, 10.0], "z": [0.0, 180.0, -45.0]}


def write_csv(path: Path, header: list[str], rows: Sequence[Sequence[str]], *,
              delimiter: str = ",", bom: bool = False, before: str = "") -> Path:
    with path.open("w", newline="", encoding="utf-8-sig" if bom else "utf-8") as fh:
        fh.write(before)
        w = csv.writer(fh, delimiter=delimiter, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)
    return path


def logger_csv(tmp_path: Path, name: str = "logger.csv", *, delimiter: str = ",",
               bom: bool = False) -> Path:
    return write_csv(tmp_path / name, ["timestamp", "temp", "gx", "gy", "gz"], LOGGER_ROWS,
                     delimiter=delimiter, bom=bom)


def spec(columns: str = LOGGER_COLUMNS) -> InputSpec:
    return InputSpec(columns=parse_columns(columns.split()))


def assert_logger_values(runs: list[Run], path: Path) -> None:
    assert len(runs) == 1
    run = runs[0]
    assert run.name == path.stem
    np.testing.assert_allclose(run.time_s, TIME_S, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.temperature_c, TEMP_C, rtol=0, atol=1e-12)
    for axis, want in RATES_DPS.items():
        np.testing.assert_allclose(run.rates_dps[axis], want, rtol=0, atol=1e-12)
    assert run.metadata["unit_time"] == "us" and run.metadata["unit_x"] == "rad/s"
    assert run.metadata["format"] == "text"


def test_logger_csv_with_a_column_map(tmp_path: Path) -> None:
    path = logger_csv(tmp_path)
    assert_logger_values(read_runs(path, spec=spec()), path)


@pytest.mark.parametrize(("delimiter", "bom"), [(";", True), (";", False), ("\t", False),
                                                (",", True)])
def test_bom_and_delimiters_are_detected(tmp_path: Path, delimiter: str, bom: bool) -> None:
    path = logger_csv(tmp_path, delimiter=delimiter, bom=bom)
    assert path.read_bytes().startswith(b"\xef\xbb\xbf") == bom
    assert_logger_values(read_runs(path, spec=spec()), path)


def test_crlf_quoted_fields_and_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "crlf.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, quoting=csv.QUOTE_ALL, lineterminator="\r\n")
        w.writerow(["timestamp", "temp", "gx", "gy", "gz"])
        w.writerows(LOGGER_ROWS)
    assert b'"1000000","20.5"' in path.read_bytes() and b"\r\n" in path.read_bytes()
    assert_logger_values(read_runs(path, spec=spec()), path)
    bad = tmp_path / "latin1.csv"
    bad.write_bytes("timestamp,temp,gx,gy,gz\n1,2,3,4,5\n# température\n".encode("latin-1"))
    # "# temp" + é: the é (0xE9 in Latin-1) is the 7th byte
    with pytest.raises(RunFileError, match=rf"{bad}: line 3: not UTF-8 text \(byte 7 of "):
        read_runs(bad, spec=spec())


def test_decimal_comma_with_semicolons(tmp_path: Path) -> None:
    rows = [(t, c.replace(".", ","), x, y, z) for t, c, x, y, z in LOGGER_ROWS]
    path = write_csv(tmp_path / "excel.csv", ["timestamp", "temp", "gx", "gy", "gz"], rows,
                     delimiter=";", bom=True)
    assert b"20,75;" in path.read_bytes()
    assert_logger_values(read_runs(path, spec=spec()), path)
    comma = write_csv(tmp_path / "comma.csv", ["timestamp", "temp", "gx", "gy", "gz"],
                      [(*LOGGER_ROWS[0][:1], "20,5", *LOGGER_ROWS[0][2:])])  # quoted by csv
    with pytest.raises(RunFileError, match="column 'temp': '20,5' is not a number"):
        read_runs(comma, spec=spec())


def test_whitespace_columns_and_comment_lines(tmp_path: Path) -> None:
    path = tmp_path / "ws.txt"
    lines = ["# exported by a logger", "timestamp   temp  gx gy gz"]
    lines += ["  ".join(r) for r in LOGGER_ROWS[:2]] + ["# a comment in the data", ""]
    lines += ["\t".join(LOGGER_ROWS[2])]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    assert_logger_values(read_runs(path, spec=spec()), path)


def test_unknown_header_lists_columns_roles_and_an_example(tmp_path: Path) -> None:
    path = logger_csv(tmp_path)
    with pytest.raises(RunFileError) as err:
        read_runs(path, spec=InputSpec())
    msg = str(err.value)
    assert f"{path}: line 1:" in msg
    assert "['timestamp', 'temp', 'gx', 'gy', 'gz']" in msg
    assert "roles needed: time, temperature, at least one of x, y, z" in msg
    assert "--columns time=timestamp:<s|ms|us|ns> temperature=temp:<degC|K|mdegC> " \
        "x=gx:<dps|rad/s|mdps|mrad/s>" in msg


def test_run_file_columns_without_the_magic_line(tmp_path: Path) -> None:
    header = ["time_s", "temperature_c", "rate_x_dps", "rate_z_dps", "note"]
    rows = [("0", "25", "0.01", "-0.02", "a"), ("0.5", "25.5", "0.015", "-0.01", "b")]
    path = write_csv(tmp_path / "nomagic.csv", header, rows)
    (run,) = read_runs(path, spec=InputSpec())
    # the same text with the magic line, read by the run-file parser
    text = "# gyrotherm-run: 1\n" + path.read_text().replace(",a\n", ",1\n").replace(",b\n",
                                                                                      ",2\n")
    truth = parse_run(text)
    assert run.axes == ("x", "z")
    np.testing.assert_array_equal(run.time_s, truth.time_s)
    np.testing.assert_array_equal(run.temperature_c, truth.temperature_c)
    for axis in ("x", "z"):
        np.testing.assert_array_equal(run.rates_dps[axis], truth.rates_dps[axis])
    assert run.metadata["schema"] == "run-file columns"


def test_units_table_conversions(tmp_path: Path) -> None:
    header = ["t_ms", "t_K", "mdps", "mrad", "deg", "ax_g", "ay_mg", "az"]
    rows = [("0", "273.15", "1000", "1000", "1", "1", "1000", "9.5"),
            ("250", "300", "-500", "0", "2", "0.5", "-250", "0")]
    path = write_csv(tmp_path / "units.csv", header, rows)
    cols = ("time=t_ms:ms temperature=t_K:K x=mdps:mdps y=mrad:mrad/s z=deg:deg/s "
            "accel_x=ax_g:g accel_y=ay_mg:mg accel_z=az:m/s2")
    (run,) = read_text(path, columns=parse_columns(cols.split()))
    np.testing.assert_allclose(run.time_s, [0.0, 0.25], atol=1e-15)
    np.testing.assert_allclose(run.temperature_c, [0.0, 26.85], atol=1e-12)
    np.testing.assert_allclose(run.rates_dps["x"], [1.0, -0.5], atol=1e-15)
    np.testing.assert_allclose(run.rates_dps["y"], [57.29577951308232, 0.0], rtol=1e-15)
    np.testing.assert_allclose(run.rates_dps["z"], [1.0, 2.0])
    np.testing.assert_allclose(run.extra["accel_x_mps2"], [9.80665, 4.903325], rtol=1e-15)
    np.testing.assert_allclose(run.extra["accel_y_mps2"], [9.80665, -2.4516625], rtol=1e-15)
    np.testing.assert_allclose(run.extra["accel_z_mps2"], [9.5, 0.0])


def test_one_column_for_two_roles_is_converted_once_each(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "same.csv", ["t", "c", "g"], [("0", "1", "2"), ("1", "2", "4")])
    (run,) = read_text(path, columns=parse_columns(
        "time=t:s temperature=c:degC x=g:mdps y=g:mdps z=g:dps".split()))
    np.testing.assert_allclose(run.rates_dps["x"], [0.002, 0.004])
    np.testing.assert_allclose(run.rates_dps["y"], [0.002, 0.004])
    np.testing.assert_allclose(run.rates_dps["z"], [2.0, 4.0])


def test_fahrenheit_millidegrees_nanoseconds(tmp_path: Path) -> None:
    rows = [("0", "212", "25000", "1"), ("1500000000", "32", "-40000", "2")]
    path = write_csv(tmp_path / "f.csv", ["ns", "f", "mc", "r"], rows)
    (a,) = read_text(path, columns=parse_columns(
        "time=ns:ns temperature=f:degF x=r:dps".split()))
    (b,) = read_text(path, columns=parse_columns(
        "time=ns:ns temperature=mc:mdegC x=r:dps".split()))
    np.testing.assert_allclose(a.time_s, [0.0, 1.5])
    np.testing.assert_allclose(a.temperature_c, [100.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(b.temperature_c, [25.0, -40.0], atol=1e-12)


@pytest.mark.parametrize(("cell", "problem"), [("abc", "'abc' is not a number"),
                                               ("", "'' is blank"),
                                               ("nan", "'nan' is not a finite number"),
                                               ("inf", "'inf' is not a finite number")])
def test_garbled_cell_names_line_and_column(tmp_path: Path, cell: str, problem: str) -> None:
    rows = [*LOGGER_ROWS]
    rows[1] = (rows[1][0], rows[1][1], rows[1][2], cell, rows[1][4])
    path = write_csv(tmp_path / "bad.csv", ["timestamp", "temp", "gx", "gy", "gz"], rows,
                     before="# comment\n")
    with pytest.raises(RunFileError, match=rf"^{path}: line 4: column 'gy': {problem}$"):
        read_runs(path, spec=spec())


def test_time_must_increase_error_names_the_line(tmp_path: Path) -> None:
    rows = [*LOGGER_ROWS, ("1040000", "21", "0", "0", "0")]
    path = write_csv(tmp_path / "t.csv", ["timestamp", "temp", "gx", "gy", "gz"], rows)
    with pytest.raises(RunFileError, match=r"line 5: column 'timestamp': time not increasing "
                       r"\(1.04 s then 1.04 s\)"):
        read_runs(path, spec=spec())


def test_wrong_field_count_and_missing_column(tmp_path: Path) -> None:
    path = tmp_path / "short.csv"
    path.write_text("timestamp,temp,gx,gy,gz\n1,2,3,4,5\n2,3,4\n", encoding="utf-8")
    with pytest.raises(RunFileError, match=r"line 3: expected 5 fields \(comma-separated\), "
                       r"got 3"):
        read_runs(path, spec=spec())
    with pytest.raises(RunFileError) as err:
        read_runs(path, spec=spec(LOGGER_COLUMNS.replace("gz", "gyro_z")))
    msg = str(err.value)
    assert "--columns z=gyro_z:rad/s: no such column" in msg
    assert "columns found with comma delimiter: ['timestamp', 'temp', 'gx', 'gy', 'gz']" in msg
    assert "columns needed: ['timestamp', 'temp', 'gx', 'gy', 'gyro_z']" in msg


def test_device_and_run_columns_split_runs_together(tmp_path: Path) -> None:
    rows = [("0", "7", "cold", "20", "1"), ("0", "7", "hot", "40", "2"),
            ("1", "7", "cold", "21", "3"), ("0", "8", "cold", "22", "4")]
    path = write_csv(tmp_path / "g.csv", ["t", "dev", "seg", "temp", "gx"], rows)
    runs = read_runs(path, spec=spec("time=t:s temperature=temp:degC x=gx:dps device=dev "
                                     "run=seg"))
    assert [r.name for r in runs] == ["g:7:cold", "g:7:hot", "g:8:cold"]
    assert [(r.metadata["device_id"], r.metadata["segment"]) for r in runs] == [
        ("7", "cold"), ("7", "hot"), ("8", "cold")]
    np.testing.assert_array_equal(runs[0].temperature_c, [20.0, 21.0])
    np.testing.assert_array_equal(runs[2].rates_dps["x"], [4.0])


def test_device_column_splits_runs(tmp_path: Path) -> None:
    rows = [("0", "7", "20", "1"), ("1", "9", "30", "2"), ("2", "7", "21", "3"),
            ("3", "9", "31", "4")]
    path = write_csv(tmp_path / "two.csv", ["t", "dev", "temp", "gx"], rows)
    runs = read_runs(path, spec=spec("time=t:s temperature=temp:degC x=gx:dps device=dev"))
    assert [r.name for r in runs] == ["two:7", "two:9"]
    assert [r.metadata["device_id"] for r in runs] == ["7", "9"]
    assert [r.metadata["instance"] for r in runs] == ["0", "1"]
    np.testing.assert_array_equal(runs[1].time_s, [1.0, 3.0])
    np.testing.assert_array_equal(runs[1].temperature_c, [30.0, 31.0])
    np.testing.assert_array_equal(runs[0].rates_dps["x"], [1.0, 3.0])


@pytest.mark.parametrize(("tokens", "problem"), [
    ("time=t:s temperature=c:degC", r"missing role\(s\) \['x\|y\|z'\]"),
    ("time=t:hours temperature=c:degC x=g:dps", "unknown time unit 'hours'; known: s, ms"),
    ("time=t temperature=c:degC x=g:dps", "role 'time' needs a unit"),
    ("time=t:s temperature=c:degC x=g:dps speed=v:m/s", "unknown role 'speed'"),
    ("time=t:s temperature=c:degC x=g:dps x=h:dps", r"role\(s\) \['x'\] given more than once"),
    ("time=t:s temperature=c:degC x=g:dps run2.csv",
     r"'run2.csv': expected ROLE=COLUMN\[:UNIT\] \(an input file\? put input files before"),
])
def test_column_map_errors(tokens: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem):
        parse_columns(tokens.split())
