"""``gyrotherm export`` reads the fitting runs again with the input options the fit was
given (recorded in the calibration's provenance): a logger's CSVs need no second
``--columns``."""

from __future__ import annotations

import json
from pathlib import Path

from gyrotherm.cli import main
from userdatakit import logger_csv

COLUMNS = ["time=timestamp:us", "temperature=temp:degC", "x=gx:rad/s", "y=gy:rad/s",
           "z=gz:rad/s"]


def test_export_rereads_csv_runs_with_the_recorded_column_map(tmp_path: Path) -> None:
    logs = [logger_csv(tmp_path / f"logger-{k}.csv", top_c=45.0 + 5 * k, seed=k)
            for k in range(2)]
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *map(str, logs), "--out", str(cal), "--model", "t2",
                 "--no-validation", "--columns", *COLUMNS]) == 0
    recorded = json.loads(cal.read_text())["provenance"]["input_options"]
    assert recorded == {"columns": COLUMNS}
    out = tmp_path / "export.json"
    assert main(["-q", "export", str(cal), "--ardupilot", str(tmp_path / "ap.param"),
                 "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert sorted(doc["fit_runs"]) == sorted(map(str, logs))
    for axis, e in doc["validation"]["axes"].items():
        # the logs' bias law is quadratic in T (userdatakit.LAW), noise 0.002 °/s: the
        # autopilot's cubic (plus ArduPilot's boot-time offset) leaves about the noise
        assert e["cubic_rms_dps"] < 0.01 < e["raw_rms_dps"], axis


def test_a_serial_captures_options_are_recorded_and_the_command_line_wins() -> None:
    import argparse

    from gyrotherm.cli._inputs import recorded_options, with_recorded_options

    keys = ("format", "columns", "delimiter", "dbc", "signals", "imu_topic",
            "temperature_topic", "rate_hz", "bad_lines")
    given = argparse.Namespace(**dict.fromkeys(keys), runs=["cap.csv"])
    given.format, given.columns = "auto", ["temperature=1:degC", "x=5:dps"]
    given.rate_hz, given.bad_lines = 50.0, "skip"
    recorded = json.loads(json.dumps(recorded_options(given)))
    assert recorded == {"columns": ["temperature=1:degC", "x=5:dps"], "rate_hz": 50.0,
                        "bad_lines": "skip"}
    bare = argparse.Namespace(**dict.fromkeys(keys), runs=["cap.csv"])
    bare.format = "auto"
    merged = with_recorded_options(bare, recorded)
    assert (merged.rate_hz, merged.bad_lines, merged.columns) == (
        50.0, "skip", ["temperature=1:degC", "x=5:dps"])
    # an explicit --bad-lines error on the command line is not overridden by the record
    explicit = argparse.Namespace(**vars(bare))
    explicit.bad_lines = "error"
    assert with_recorded_options(explicit, recorded).bad_lines == "error"
