"""One set of CLI conventions (src/gyrotherm/cli/_conventions.py), checked on every
subcommand's parser, so that a new command cannot break them, and end to end on the
commands that write outputs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import build_parser, main
from gyrotherm.client._listen import _parser as listen_parser
from gyrotherm.client._record import _parser as record_parser

#: Subcommands that must exist (the walk below covers any others too).
COMMANDS = {"gyrotherm sim chamber", "gyrotherm sim stream", "gyrotherm fit",
            "gyrotherm evaluate", "gyrotherm paper", "gyrotherm diagnose", "gyrotherm demo",
            "gyrotherm run", "gyrotherm listen", "gyrotherm record"}


def _leaves() -> dict[str, argparse.ArgumentParser]:
    """Every subcommand parser that runs something, plus listen's own parser (with the
    formatter the CLI gives it)."""
    out = {prog: p for prog, p in conv.walk(build_parser())
           if p.get_default("func") is not None}
    listen = listen_parser()
    listen.formatter_class = conv.DefaultsFormatter
    out["gyrotherm listen"] = listen
    record = record_parser()
    record.formatter_class = conv.DefaultsFormatter
    out["gyrotherm record"] = record
    return out


def _options(p: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in p._actions if a.option_strings and not isinstance(
        a, (argparse._HelpAction, argparse._VersionAction))]


def test_every_subcommand_is_walked() -> None:
    assert set(_leaves()) >= COMMANDS


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_help_shows_every_default(prog: str) -> None:
    p = _leaves()[prog]
    fmt = p._get_formatter()
    for a in _options(p):
        if a.nargs == 0 or a.required:  # flags (off unless given), required options
            continue
        assert a.help, f"{prog} {a.option_strings}: no help"
        assert "default" in fmt._expand_help(a).lower(), f"{prog} {a.option_strings}"
    text = p.format_help()
    assert "--quiet" in text and "default" in text


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_quiet_json_and_out_mean_the_same_everywhere(prog: str) -> None:
    p = _leaves()[prog]
    by_flag = {s: a for a in _options(p) for s in a.option_strings}
    assert by_flag["-q"] is by_flag["--quiet"] and by_flag["-q"].dest == "quiet"
    if "--json" in by_flag:
        a = by_flag["--json"]
        assert (a.nargs, a.const, a.default) == ("?", "-", None), prog
        assert "stdout" in (a.help or "")
    if "--out" in by_flag:
        assert any(w in (by_flag["--out"].help or "") for w in ("FILE", "DIRECTORY")), prog


def test_quiet_before_or_after_the_subcommand() -> None:
    parser = build_parser()
    base = ["fit", "a.csv", "--out", "c.json"]
    assert parser.parse_args(base).quiet is False
    assert parser.parse_args(["-q", *base]).quiet is True
    assert parser.parse_args([*base, "-q"]).quiet is True
    assert parser.parse_args(["sim", "chamber", "--out", "d", "--quiet"]).quiet is True
    assert listen_parser().parse_args(["--vehicle", "v", "--sensor", "s", "-q"]).quiet


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    out = tmp_path_factory.mktemp("runs") / "nested" / "dir"  # parents created
    assert main(["-q", "sim", "chamber", "--heating-min", "5", "30", "--out", str(out),
                 "--seed", "4", "--rate-hz", "1", "--hold-s", "600"]) == 0
    return sorted(str(p) for p in out.glob("*.csv"))


def test_json_to_stdout_or_file_replaces_the_table(
        runs: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    cal = tmp_path / "a" / "b" / "cal.json"  # parents created
    assert main(["fit", *runs, "--out", str(cal), "--json", "-q"]) == 0
    fitted = json.loads(capsys.readouterr().out)  # the whole stdout is the JSON
    assert fitted["calibration"] == str(cal) and cal.is_file()
    assert set(fitted["coefficients_physical"]) == {"x", "y", "z"}
    assert {s["run"] for s in fitted["leave_one_run_out"]} == {"heat-05min", "heat-30min"}
    target = tmp_path / "deep" / "scores.json"
    assert main(["-q", "evaluate", str(cal), runs[0], "--json", str(target)]) == 0
    assert capsys.readouterr().out == ""  # no table when JSON goes to a file
    to_file = json.loads(target.read_text())
    assert main(["-q", "evaluate", str(cal), runs[0], "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == to_file
    assert main(["-q", "evaluate", str(cal), runs[0]]) == 0
    assert "comp RMS" in capsys.readouterr().out  # the table without --json
    listing = tmp_path / "sim.json"
    assert main(["sim", "chamber", "--heating-min", "5", "--out", str(tmp_path / "r"),
                 "--rate-hz", "1", "--hold-s", "300", "--json", str(listing), "-q"]) == 0
    assert capsys.readouterr().out == ""
    assert [Path(r["path"]).name for r in json.loads(listing.read_text())["runs"]] == [
        "heat-05min.csv"]


def test_progress_is_plain_lines_off_a_terminal(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "chamber", "--heating-min", "5", "10", "--out", str(tmp_path),
                 "--rate-hz", "1", "--hold-s", "300"]) == 0
    err = capsys.readouterr().err  # captured: not a tty
    assert "\r" not in err
    assert err.splitlines() == ["simulating: 2/2"]


def test_swapped_arguments_get_a_hint(
        runs: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *runs, "--out", str(cal), "--no-validation"]) == 0
    capsys.readouterr()
    assert main(["evaluate", runs[0], str(cal)]) == 2
    err = capsys.readouterr().err
    assert (f"{runs[0]}: the first argument looks like a run file, the calibration comes "
            "first: gyrotherm evaluate CAL RUNS...") in err
    assert f"gyrotherm evaluate {cal} {runs[0]}" in err
    assert main(["evaluate", runs[0], runs[1]]) == 2
    assert "the calibration comes first" in capsys.readouterr().err
    assert main(["fit", runs[0], str(cal), "--out", str(tmp_path / "c2.json")]) == 2
    assert f"{cal}: is a calibration file, not a run" in capsys.readouterr().err
    assert main(["diagnose", runs[0], str(cal)]) == 2
    assert f"{cal}: is a calibration file, not a run" in capsys.readouterr().err
    # an output pointing at an existing run file would destroy it: refused, file intact
    before = Path(runs[1]).read_bytes()
    assert main(["-q", "fit", runs[0], "--out", runs[1]]) == 2
    assert f"--out {runs[1]}: is an existing run file" in capsys.readouterr().err
    assert main(["-q", "evaluate", str(cal), runs[0], "--json", runs[1]]) == 2
    assert f"--json {runs[1]}: is an existing run file" in capsys.readouterr().err
    fresh = tmp_path / "fresh.json"  # checked before any work: no calibration written
    assert main(["-q", "fit", runs[0], "--out", str(fresh), "--json", runs[1]]) == 2
    assert f"--json {runs[1]}: is an existing run file" in capsys.readouterr().err
    assert not fresh.exists()
    assert Path(runs[1]).read_bytes() == before


def test_paper_json_replaces_both_tables(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["paper", "--rate-hz", "0.5", "--json", "-q"]) == 0
    doc = json.loads(capsys.readouterr().out)  # nothing but the JSON on stdout
    assert list(doc["table1"]["rows"])[-2:] == ["mean (eq. 12)", "pooled"]
    assert doc["table1"]["truth"]["T*dT"] == pytest.approx(-0.0004)
    assert "paper (eq.12)" in doc["table2"]["columns"]


def test_outputs_get_their_parent_directories(tmp_path: Path) -> None:
    log = tmp_path / "a" / "b" / "bus.log"
    assert main(["sim", "stream", "--chamber", "1", "--rate-hz", "1", "--hold-s", "30",
                 "--interface", "none", "--write-candump", str(log), "--speed", "0",
                 "-q"]) == 0
    assert log.read_text().startswith("(")
