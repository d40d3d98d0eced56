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


def test_unknown_numeric_columns_are_kept_in_extra() -> None:
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
        (HEADER + "0,20,0.1\n1,21,abc\n", "line 5: column 'rate_x_dps': 'abc' is not a number"),
        (HEADER + "0,20,0.1\n1,,0.2\n", "line 5: column 'temperature_c' is blank"),
        (HEADER + "0,20,0.1\n1,21, \n", "line 5: column 'rate_x_dps' is blank"),
        (HEADER + "0,20,0.1\n1,2_1,0.2\n", "line 5: column 'temperature_c': '2_1' is not a"),
        (HEADER + "0,20,0.1\n\n1,21,0.2\n", "line 5: blank line inside the data"),
        (HEADER + "0,20,0.1\n# late comment\n", "line 5: expected 3 fields, got 1"),
        (HEADER + "0,20,0.1\n1,21,0.2,9\n", "line 5: expected 3 fields, got 4"),
        ("# gyrotherm-run: 1\ntime_s,time_s,temperature_c,rate_x_dps\n", "duplicate columns"),
    ],
)
def test_bad_files_name_line_and_problem(text: str, message: str) -> None:
    with pytest.raises(RunFileError, match=message.replace("(", r"\(")) as info:
        parse_run(text, source="bad.csv")
    assert str(info.value).startswith("bad.csv")


NOTE_HEADER = "# gyrotherm-run: 1\ntime_s,temperature_c,note,rate_x_dps,humidity\n"


@pytest.mark.parametrize(
    "note",
    ["abc", "", " ", "nan", "inf", "1_0", "0x10"],
    ids=["text", "blank", "space", "nan", "inf", "underscore", "hex"],
)
def test_unknown_column_that_is_not_all_finite_numbers_is_ignored(note: str) -> None:
    run = parse_run(NOTE_HEADER + f"0,20,1.5,0.1,40\n1,21,{note},0.2,41\n2,22,3,0.3,42\n")
    assert "note" not in run.extra
    np.testing.assert_array_equal(run.extra["humidity"], [40, 41, 42])
    np.testing.assert_array_equal(run.time_s, [0, 1, 2])
    np.testing.assert_array_equal(run.temperature_c, [20, 21, 22])
    np.testing.assert_array_equal(run.rates_dps["x"], [0.1, 0.2, 0.3])


def test_unknown_numeric_columns_are_kept_next_to_a_text_column() -> None:
    text = "# gyrotherm-run: 1\ntime_s,temperature_c,rate_x_dps,a,note,b\n"
    text += "".join(f"{i},{20 + i},{i / 10},{2 * i},row {i},{-i}\n" for i in range(4))
    run = parse_run(text)
    assert set(run.extra) == {"a", "b"}
    np.testing.assert_array_equal(run.extra["a"], [0, 2, 4, 6])
    np.testing.assert_array_equal(run.extra["b"], [0, -1, -2, -3])


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("1,21,abc,0.2x,41", "line 4: column 'rate_x_dps': '0.2x' is not a number"),
        ("1,21,abc,,41", "line 4: column 'rate_x_dps' is blank"),
        ("1,nan,abc,0.2,41", "line 4: column 'temperature_c' is not a finite number"),
        ("1,21,abc,0.2", "line 4: expected 5 fields, got 4"),
    ],
)
def test_known_columns_stay_strict_next_to_a_text_column(row: str, message: str) -> None:
    text = "# gyrotherm-run: 1\ntime_s,temperature_c,note,rate_x_dps,humidity\n"
    with pytest.raises(RunFileError, match=message) as info:
        parse_run(text + f"0,20,x,0.1,40\n{row}\n", source="notes.csv")
    assert str(info.value).startswith("notes.csv: ")


def test_text_column_in_a_large_file_is_ignored(tmp_path: Path) -> None:
    n = 20_000
    t = np.arange(n) * 0.01
    lines = [f"{t[i]:.2f},{20 + t[i]:.4f},{i % 7 - 3},ok,{i}\n" for i in range(n)]
    lines[n - 1] = f"{t[n - 1]:.2f},{20 + t[n - 1]:.4f},1,,{n - 1}\n"  # blank note on the last row
    path = tmp_path / "big.csv"
    header = "# gyrotherm-run: 1\ntime_s,temperature_c,rate_z_dps,note,row\n"
    path.write_text(header + "".join(lines))
    run = read_run(path)
    assert len(run) == n and run.axes == ("z",) and set(run.extra) == {"row"}
    np.testing.assert_array_equal(run.extra["row"], np.arange(n))
    np.testing.assert_allclose(run.temperature_c, 20 + np.round(t, 2), atol=5e-5)


def test_clean_file_takes_one_parsing_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    from gyrotherm.codecs import _runbody as _runfile

    chunks: list[int] = []
    calls: list[object] = []
    real_lines, real = _runfile._loadtxt_lines, _runfile._loadtxt

    def counting_lines(lines: list[str], width: int) -> np.ndarray:
        chunks.append(len(lines))
        return real_lines(lines, width)

    def counting(text: str, usecols: list[int] | None = None) -> np.ndarray:
        calls.append(usecols)
        return real(text, usecols)

    monkeypatch.setattr(_runfile, "_loadtxt_lines", counting_lines)
    monkeypatch.setattr(_runfile, "_loadtxt", counting)
    parse_run(HEADER + "".join(f"{i},{20 + i},0.{i}\n" for i in range(100)))
    assert (chunks, calls) == ([100], [])  # one chunk, no slow path
    chunks.clear()
    parse_run(NOTE_HEADER + "".join(f"{i},{20 + i},n{i},0.{i},{i}\n" for i in range(100)))
    assert chunks == [100]  # the fast path fails on the text column, then:
    assert calls == [[0, 1, 3], [2], [4]]  # known columns; each unknown on its own


def test_reader_columns_are_not_copied_again() -> None:
    """The reader's read-only columns are the run's arrays (no second copy of a large
    log), and still cannot be written; a caller's writable array is copied."""
    run = parse_run(HEADER + "0,20,0.1\n1,21,0.2\n")
    with pytest.raises(ValueError):
        run.rates_dps["x"][0] = 5.0
    again = Run(name="r", time_s=run.time_s, temperature_c=run.temperature_c,
                rates_dps=run.rates_dps)
    assert again.time_s is run.time_s
    mine = np.array([0.0, 1.0])
    copied = Run(name="c", time_s=mine, temperature_c=mine, rates_dps={"x": mine})
    mine[0] = 9.0
    assert copied.time_s[0] == 0.0


def test_missing_file_is_a_run_file_error(tmp_path: Path) -> None:
    with pytest.raises(RunFileError, match="cannot read run file"):
        read_run(tmp_path / "nope.csv")


def test_format_is_stable_text() -> None:
    run = parse_run(HEADER + "0,20,0.1\n0.5,20.25,-0.125\n")
    assert format_run(run) == HEADER + "0,20,0.1\n0.5,20.25,-0.125\n"


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
@pytest.mark.parametrize("trailing", ["", "\n", "\n\n  \n"])
def test_body_parsed_in_chunks_equals_small_parse(
    monkeypatch: pytest.MonkeyPatch, newline: str, trailing: str
) -> None:
    """The body is handed to numpy in ~chunk-sized pieces split at line ends: with a
    tiny chunk (every few lines, some lines longer than a chunk) every value and the
    line numbers in errors are the same as with one piece."""
    from gyrotherm.codecs import _runbody as _runfile

    rng = np.random.default_rng(5)
    rows = [f"{i * 0.1:.1f},{20 + rng.normal():.6f},{rng.normal():.9f}" for i in range(300)]
    text = newline.join(["# gyrotherm-run: 1", "# name: chunks", "time_s,temperature_c,rate_x_dps",
                         *rows]) + trailing
    whole = parse_run(text)
    monkeypatch.setattr(_runfile, "_CHUNK_CHARS", 7)
    chunked = parse_run(text)
    expected = np.array([[float(v) for v in r.split(",")] for r in rows])
    for run in (whole, chunked):
        assert len(run) == 300
        np.testing.assert_array_equal(run.time_s, expected[:, 0])
        np.testing.assert_array_equal(run.temperature_c, expected[:, 1])
        np.testing.assert_array_equal(run.rates_dps["x"], expected[:, 2])
    broken = text.replace(rows[150], rows[150].replace(",", ",x", 1), 1)
    with pytest.raises(RunFileError, match=r"line 154: column 'temperature_c'"):
        parse_run(broken)
    gap = text.replace(rows[200], "", 1)
    with pytest.raises(RunFileError, match=r"line 204: blank line inside the data"):
        parse_run(gap)
