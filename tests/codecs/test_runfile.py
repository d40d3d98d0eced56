"""Run files (CSV version 1): round trip and clear errors for bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gyrotherm import RunFileError
from gyrotherm.codecs import Run, format_run, parse_run, read_run, write_run

HEADER = "# gyrotherm-run: 1\n# name: tiny\ntime_s,temperature_c,rate_x_dps\n"


def test_round_trip_keeps_every_column(tmp_path: Path) -> None:
    t = np.arange(5) * 0.1
    run = Run(
        name="r1",
        time_s=t,
        temperature_c=20 + t,
        rates_dps={"x": t * 2, "z": -t},
        chamber_c=21 + t,
        true_bias_dps={"x": t * 3},
        metadata={"seed": "7"},
        extra={"true_temperature_c": 20.5 + t},
    )
    back = read_run(write_run(run, tmp_path / "r1.csv"))
    assert back.name == "r1" and back.axes == ("x", "z")
    assert back.metadata["seed"] == "7"
    np.testing.assert_allclose(back.temperature_c, run.temperature_c)
    np.testing.assert_allclose(back.rates_dps["z"], run.rates_dps["z"])
    assert back.chamber_c is not None
    np.testing.assert_allclose(back.chamber_c, 21 + t)
    np.testing.assert_allclose(back.true_bias_dps["x"], t * 3)
    np.testing.assert_allclose(back.extra["true_temperature_c"], 20.5 + t)
    assert len(back.sha256) == 64


def test_arrays_are_read_only() -> None:
    run = parse_run(HEADER + "0,20,0.1\n1,21,0.2\n")
    with pytest.raises(ValueError):
        run.time_s[0] = 5.0


def test_unknown_columns_are_ignored_by_tools() -> None:
    run = parse_run("# gyrotherm-run: 1\ntime_s,humidity,temperature_c,rate_y_dps\n0,50,20,1\n")
    assert run.axes == ("y",)
    assert run.extra["humidity"][0] == 50
    assert run.name == "<memory>"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "line 1: empty file"),
        ("time_s,temperature_c,rate_x_dps\n0,1,2\n", "line 1: expected '# gyrotherm-run: 1'"),
        ("# gyrotherm-run: 2\ntime_s,temperature_c,rate_x_dps\n", "unsupported run file version"),
        ("# gyrotherm-run: 1\n", "line 2: missing header row"),
        ("# gyrotherm-run: 1\ntime_s,rate_x_dps\n0,1\n", "line 2: missing column 'temperature_c'"),
        ("# gyrotherm-run: 1\ntemperature_c,rate_x_dps\n0,1\n", "missing column 'time_s'"),
        ("# gyrotherm-run: 1\ntime_s,temperature_c\n0,1\n", "line 2: missing rate column"),
        (HEADER, "line 4: no data rows"),
        (HEADER + "0,20,0.1\n1,nan,0.2\n", "line 5: column 'temperature_c' is not a finite"),
        (HEADER + "0,20,0.1\n0,21,0.2\n", "line 5: time_s not increasing"),
        (HEADER + "0,20,0.1\n1,21\n", "line 5: expected 3 fields, got 2"),
        (HEADER + "0,20,0.1\n1,21,abc\n", "line 5: 'abc' is not a number"),
        ("# gyrotherm-run: 1\ntime_s,time_s,temperature_c,rate_x_dps\n", "duplicate columns"),
    ],
)
def test_bad_files_name_line_and_problem(text: str, message: str) -> None:
    with pytest.raises(RunFileError, match=message.replace("(", r"\(")) as info:
        parse_run(text, source="bad.csv")
    assert str(info.value).startswith("bad.csv")


def test_missing_file_is_a_run_file_error(tmp_path: Path) -> None:
    with pytest.raises(RunFileError, match="cannot read run file"):
        read_run(tmp_path / "nope.csv")


def test_format_is_stable_text() -> None:
    run = parse_run(HEADER + "0,20,0.1\n0.5,20.25,-0.125\n")
    assert format_run(run) == HEADER + "0,20,0.1\n0.5,20.25,-0.125\n"
