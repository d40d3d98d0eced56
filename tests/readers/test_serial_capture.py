"""A serial capture read as a user has it: a PuTTY log of a BMI270 printed over UART,
without header or time stamps, with a banner and damaged lines (tests/readers/data/
putty-bmi270/SOURCE.md). Truth: the csv module on the excerpts, and the data curator's
cleaned file of the whole captures (../shared, its SOURCE.md)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers import InputSpec, parse_columns, read_runs

DATA = Path(__file__).parent / "data" / "putty-bmi270"
COLUMNS = "temperature=1:degC x=5:dps y=6:dps z=7:dps".split()
_RAW = Path("data/measured/bmi270-peltier-laptop")
SHARED = next((d / _RAW for d in (Path(__file__).resolve().parents[3] / "shared",
                                  Path("/work/shared")) if (d / _RAW).is_dir()),
              Path("/work/shared") / _RAW)


def _spec(*, bad_lines: str = "error", rate_hz: float | None = 50.0) -> InputSpec:
    return InputSpec(columns=parse_columns(COLUMNS, rate_hz=rate_hz), bad_lines=bad_lines)


def _good_rows(path: Path, width: int = 7) -> list[list[float]]:
    """The lines of the capture the csv module reads as ``width`` numbers."""
    out = []
    with path.open(newline="") as fh:
        for row in csv.reader(fh):
            try:
                values = [float(c) for c in row]
            except ValueError:
                continue
            if len(values) == width:
                out.append(values)
    return out


def test_a_damaged_line_is_an_error_naming_it_and_the_way_out() -> None:
    with pytest.raises(RunFileError, match=r"hot_head.csv: line 2: expected 7 fields "
                       r"\(comma-separated\), got 6 \(a serial capture with damaged lines\? "
                       r"--bad-lines skip"):
        read_runs(DATA / "hot_head.csv", spec=_spec())


def test_skipped_lines_are_dropped_listed_and_the_rest_read_as_logged() -> None:
    (run,) = read_runs(DATA / "hot_head.csv", spec=_spec(bad_lines="skip"))
    rows = np.array(_good_rows(DATA / "hot_head.csv"))
    assert len(run) == len(rows) == 20 - 3  # banner, line 2 (6 fields), line 13 (8 fields)
    np.testing.assert_array_equal(run.temperature_c, rows[:, 0])
    for j, axis in zip((4, 5, 6), "xyz", strict=True):
        np.testing.assert_array_equal(run.rates_dps[axis], rows[:, j])
    assert run.metadata["dropped_lines"] == (
        "2: line 2: expected 7 fields (comma-separated), got 6; "
        "line 13: expected 7 fields (comma-separated), got 8")
    assert run.metadata["header"].startswith("none")
    # no time stamps: row index / 50 Hz, said to be nominal
    np.testing.assert_allclose(run.time_s, np.arange(len(rows)) * 0.02, rtol=0, atol=1e-15)
    assert run.metadata["time_source"].startswith("nominal: row index / 50 Hz")


def test_a_garbled_token_in_a_mapped_column_drops_its_line_only_when_mapped() -> None:
    # cold_head.csv line 9: gyro_y (column 6) is '-0.3-0.31'
    (run,) = read_runs(DATA / "cold_head.csv", spec=_spec(bad_lines="skip"))
    assert len(run) == 12 - 2
    assert run.metadata["dropped_lines"] == "1: line 9: column '6': '-0.3-0.31' is not a number"
    assert 13.271484 not in run.temperature_c
    # x and z alone: line 9's mapped cells are fine, and it is kept
    spec = InputSpec(columns=parse_columns("temperature=1:degC x=5:dps z=7:dps".split(),
                                           rate_hz=50.0))
    (run,) = read_runs(DATA / "cold_head.csv", spec=spec)
    assert len(run) == 11 and "dropped_lines" not in run.metadata
    assert run.temperature_c[7] == 13.271484 and run.rates_dps["x"][7] == 0.12


def test_no_header_without_columns_shows_the_first_line_by_column_number() -> None:
    with pytest.raises(RunFileError, match=r"cold_head.csv: line 2: the file has no header "
                       r"\(its lines are numbers, e.g. 1: 13.255859, 2: 0.075, .* 7: -0.18\): "
                       r"give the columns by number"):
        read_runs(DATA / "cold_head.csv", spec=InputSpec())
    with pytest.raises(RunFileError, match=r"--columns x=8:dps: no such column \(the file has "
                       r"no header: its columns are numbered 1 to 7"):
        read_runs(DATA / "cold_head.csv", spec=InputSpec(columns=parse_columns(
            "temperature=1:degC x=8:dps".split(), rate_hz=50.0)))


def test_rate_hz_and_a_time_column_are_one_or_the_other() -> None:
    with pytest.raises(ConfigError, match="--rate-hz 50 with a time column"):
        parse_columns("time=1:s temperature=2:degC x=3:dps".split(), rate_hz=50.0)
    with pytest.raises(ConfigError, match="--rate-hz 0: expected a sample rate > 0 Hz"):
        parse_columns(COLUMNS, rate_hz=0.0)
    with pytest.raises(ConfigError, match=r"missing role\(s\) \['time'\]"):
        parse_columns(COLUMNS)


def test_whitespace_capture_with_a_time_column(tmp_path: Path) -> None:
    # a headerless log with its own time stamps (ms) and a blank line: no --rate-hz
    p = tmp_path / "minicom.log"
    p.write_text("1000 25.5 0.10\n1020 25.5 0.12\n\n1040 25.6 0.11\n", encoding="utf-8")
    spec = InputSpec(columns=parse_columns("time=1:ms temperature=2:degC z=3:dps".split()))
    (run,) = read_runs(p, spec=spec)
    np.testing.assert_allclose(run.time_s, [1.0, 1.02, 1.04])
    np.testing.assert_allclose(run.rates_dps["z"], [0.10, 0.12, 0.11])


def _one(tmp_path: Path, text: str, columns: str, **spec: object) -> Run:
    p = tmp_path / "capture.csv"
    p.write_text(text, encoding="utf-8")
    (run,) = read_runs(p, spec=InputSpec(columns=parse_columns(columns.split(), rate_hz=10.0),
                                         **spec))  # type: ignore[arg-type]
    return run


def test_what_makes_a_first_line_data_and_not_a_header(tmp_path: Path) -> None:
    # a trailing delimiter (an empty last field) is still a line of numbers
    run = _one(tmp_path, "25.0,0.1,0.2,\n25.1,0.2,0.3,\n", "temperature=1:degC x=3:dps")
    np.testing.assert_array_equal(run.rates_dps["x"], [0.2, 0.3])
    # a damaged first data line (mostly numbers) is data, dropped with --bad-lines skip
    run = _one(tmp_path, "25.0,0.1-0.2,0.3\n25.1,0.2,0.4\n25.2,0.3,0.5\n",
               "temperature=1:degC x=2:dps", bad_lines="skip")
    np.testing.assert_array_equal(run.temperature_c, [25.1, 25.2])
    assert run.metadata["dropped_lines"] == "1: line 1: column '2': '0.1-0.2' is not a number"
    # a capture starting with a one-field fragment: the delimiter comes from the lines after
    run = _one(tmp_path, "-0.06\n25.0,0.1,0.2\n25.1,0.2,0.3\n",
               "temperature=1:degC z=3:dps", bad_lines="skip")
    np.testing.assert_array_equal(run.rates_dps["z"], [0.2, 0.3])
    assert run.metadata["delimiter"] == "comma"
    # integer labels 0..n-1 (a dataframe without column names) are a header, not data
    p = tmp_path / "frame.csv"
    p.write_text("0,1,2\n1.0,25.0,0.1\n2.0,25.1,0.2\n", encoding="utf-8")
    (run,) = read_runs(p, spec=InputSpec(columns=parse_columns(
        "time=0:s temperature=1:degC x=2:dps".split())))
    np.testing.assert_array_equal(run.time_s, [1.0, 2.0])


def test_a_blank_group_label_is_a_damaged_line(tmp_path: Path) -> None:
    text = "a,25.0,0.1\n,25.1,0.2\na,25.2,0.3\nb,30.0,0.4\n"
    p = tmp_path / "g.csv"
    p.write_text(text, encoding="utf-8")
    spec = InputSpec(columns=parse_columns("device=1 temperature=2:degC x=3:dps".split(),
                                           rate_hz=10.0), bad_lines="skip")
    runs = read_runs(p, spec=spec)
    assert [(r.metadata["device_id"], len(r)) for r in runs] == [("a", 2), ("b", 1)]
    assert runs[0].metadata["dropped_lines"] == "1: line 2: column '1' is blank"


@pytest.mark.skipif(not SHARED.is_dir(), reason="shared measured data not present")
def test_whole_captures_match_the_curators_cleaned_file() -> None:
    clean = {"cold": [], "hot": []}  # type: dict[str, list[dict[str, str]]]
    with (SHARED / "bmi270_static_clean.csv").open(newline="") as fh:
        for row in csv.DictReader(fh):
            clean[row["segment"]].append(row)
    for segment, name in (("cold", "BMI_270_cold_test_.csv"), ("hot", "BMI_270_hot_test.csv")):
        (run,) = read_runs(SHARED / "raw" / name, spec=_spec(bad_lines="skip"))
        rows = clean[segment]
        assert len(run) == len(rows)  # 3255 and 6533 (SOURCE.md)
        np.testing.assert_array_equal(run.temperature_c, [float(r["temp_degC"]) for r in rows])
        for axis in "xyz":
            np.testing.assert_array_equal(run.rates_dps[axis],
                                          [float(r[f"gyro_{axis}_dps"]) for r in rows])
        np.testing.assert_allclose(run.time_s, [float(r["t_nominal_s"]) for r in rows],
                                   rtol=0, atol=1e-9)
    assert [len(r) for r in (clean["cold"], clean["hot"])] == [3255, 6533]
