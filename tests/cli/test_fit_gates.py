"""``fit``'s quality gates, ``--force``, strict JSON, ``evaluate`` with nothing to score,
and the one-line report of an unexpected exception.

Runs are simulated chamber runs (seeded) changed in one known way each; the measured
values the gates report are checked against the same quantity computed here from the
run written (numpy on the file's columns), not taken from gyrotherm.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.cli._guard import EXIT_INTERNAL_ERROR
from gyrotherm.cli._jsonsafe import dumps
from gyrotherm.codecs import Run, read_run, write_run
from gyrotherm.compensation import load_calibration
from gyrotherm.compensation._quality import (
    MAX_GYRO_RATE_DPS,
    MIN_DISTINCT_TEMPERATURES,
    MIN_TEMPERATURE_SPAN_C,
)
from gyrotherm.sim import chamber_runs


@pytest.fixture(scope="module")
def runs() -> list[Run]:
    return chamber_runs([10, 20], seed=7, rate_hz=1.0)


def _write(tmp: Path, runs: list[Run]) -> list[str]:
    return [str(write_run(r, tmp / f"{r.name}.csv")) for r in runs]


def _error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.splitlines()
    errors = [e for e in err if e.startswith("gyrotherm: error:")]
    assert len(errors) == 1 and err[-1] == errors[0], err
    return errors[0]


def _narrow(run: Run, lo_c: float, hi_c: float) -> Run:
    keep = (run.temperature_c >= lo_c) & (run.temperature_c <= hi_c)
    return replace(run, time_s=run.time_s[keep], temperature_c=run.temperature_c[keep],
                   rates_dps={a: v[keep] for a, v in run.rates_dps.items()},
                   chamber_c=None, true_bias_dps={}, extra={})


def test_chamber_runs_pass_every_refusing_gate(runs: list[Run], tmp_path: Path) -> None:
    files = _write(tmp_path, runs)
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "cal.json"),
                 "--json", str(tmp_path / "fit.json")]) == 0
    doc = json.loads((tmp_path / "fit.json").read_text())
    gates = {g["name"]: g for g in doc["quality"]}
    assert all(g["passed"] for g in gates.values() if g["refuses"]), gates
    temps = np.concatenate([read_run(f).temperature_c for f in files])
    assert gates["temperature-span"]["measured"] == pytest.approx(np.ptp(temps), abs=0.1)
    assert gates["rows"]["measured"] == len(temps)
    cal = load_calibration(tmp_path / "cal.json")
    assert [g["name"] for g in cal.provenance["quality"]] == list(gates)
    # 1-Hz runs: only the (non-refusing) advice to log faster
    assert [w.split(":")[0] for w in cal.provenance["quality_warnings"]] == [
        "sample-rate-recommended"]


def test_stuck_temperature_is_refused_naming_gate_value_and_threshold(
        runs: list[Run], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    stuck = [replace(r, temperature_c=np.zeros(len(r)), name=f"stuck{i}", chamber_c=None)
             for i, r in enumerate(runs)]
    files = _write(tmp_path, stuck)
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "cal.json")]) == 2
    line = _error_line(capsys)
    assert "stuck0.csv" in line and "--force" in line
    assert (f"temperature-stuck: 1 distinct readings (threshold "
            f"{MIN_DISTINCT_TEMPERATURES} distinct readings) refused") in line
    assert not (tmp_path / "cal.json").exists()


def test_narrow_span_refused_then_forced_with_the_warning_in_provenance(
        runs: list[Run], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    narrow = [_narrow(r, 20.0, 23.0) for r in runs]
    files = _write(tmp_path, narrow)
    span = float(np.ptp(np.concatenate([read_run(f).temperature_c for f in files])))
    out = tmp_path / "cal.json"
    argv = ["-q", "fit", *files, "--out", str(out), "--model", "t2"]
    assert main(argv) == 2
    line = _error_line(capsys)
    m = re.search(r"temperature-span: ([0-9.]+) °C \(threshold ([0-9.]+) °C\) refused", line)
    assert m, line
    # the gate measures the fit's input, the estimated T̂ (Kalman-smoothed readings)
    assert float(m.group(1)) == pytest.approx(span, abs=0.1)
    assert float(m.group(2)) == MIN_TEMPERATURE_SPAN_C
    assert main([*argv, "--force"]) == 0, capsys.readouterr().err
    warnings = load_calibration(out).provenance["quality_warnings"]
    assert any(w.startswith("temperature-span:") for w in warnings), warnings


def test_rate_in_the_wrong_unit_is_refused(runs: list[Run], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    mdps = [replace(r, rates_dps={a: v * 1000.0 + 5000.0 for a, v in r.rates_dps.items()},
                    true_bias_dps={}) for r in runs]
    files = _write(tmp_path, mdps)
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "cal.json"), "--rest",
                 "all"]) == 2
    line = _error_line(capsys)
    assert "rate-range:" in line and f"(threshold {MAX_GYRO_RATE_DPS:g} °/s) refused" in line


def test_evaluate_with_nothing_at_rest_exits_2(runs: list[Run], tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """A 25-s log turning at 30 °/s throughout: rest detection keeps none of its rows, so
    there is nothing to score: exit 2 naming the file, not a table of NaN."""
    files = _write(tmp_path, runs)
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "cal.json")]) == 0
    run = runs[0]
    short = replace(run, name="short", time_s=run.time_s[:25], extra={},
                    temperature_c=run.temperature_c[:25], chamber_c=None, true_bias_dps={},
                    rates_dps={a: v[:25] + (30.0 if a == "x" else 0.0)
                               for a, v in run.rates_dps.items()})
    (path,) = _write(tmp_path, [short])
    capsys.readouterr()
    assert main(["-q", "evaluate", "--json", "-", str(tmp_path / "cal.json"), path]) == 2
    line = _error_line(capsys)
    assert "short.csv" in line and "nothing to score" in line
    assert main(["-q", "evaluate", "--json", "-", "--rest", "all", str(tmp_path / "cal.json"),
                 path]) == 0
    doc = json.loads(capsys.readouterr().out,
                     parse_constant=lambda c: pytest.fail(f"bare {c} in JSON"))
    assert {s["run"] for s in doc["scores"]} == {"short"}


def test_json_has_no_bare_nan() -> None:
    text = dumps({"a": [1.0, float("nan")], "b": {"c": float("inf")}, "d": "x"})
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c}"))
    assert doc["a"] == [1.0, None] and doc["b"]["c"] is None
    assert set(doc["null_reasons"]) == {"a[1]", "b.c"}


def test_unexpected_exception_is_one_line_and_a_log_file(
        runs: list[Run], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    import gyrotherm.cli._offline as offline

    def broken(_args: object) -> int:
        raise ZeroDivisionError("a planted bug")

    monkeypatch.setattr(offline, "cmd_fit", broken)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.delenv("GYROTHERM_DEBUG", raising=False)
    files = _write(tmp_path, runs[:1])
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "c.json")]) == EXIT_INTERNAL_ERROR
    (line,) = capsys.readouterr().err.splitlines()
    assert "ZeroDivisionError: a planted bug" in line and "--debug" in line
    (log,) = (tmp_path / "state" / "gyrotherm").glob("gyrotherm-crash-*.log")
    assert str(log) in line
    assert "Traceback" in log.read_text() and "a planted bug" in log.read_text()
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "-q", "fit", *files, "--out", str(tmp_path / "c.json")])


def test_ctrl_c_is_one_line(runs: list[Run], tmp_path: Path,
                            capsys: pytest.CaptureFixture[str],
                            monkeypatch: pytest.MonkeyPatch) -> None:
    import gyrotherm.cli._offline as offline

    def interrupted(_args: object) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(offline, "cmd_fit", interrupted)
    monkeypatch.delenv("GYROTHERM_DEBUG", raising=False)
    files = _write(tmp_path, runs[:1])
    assert main(["-q", "fit", *files, "--out", str(tmp_path / "c.json")]) == 130
    assert capsys.readouterr().err.splitlines() == ["gyrotherm: interrupted"]
