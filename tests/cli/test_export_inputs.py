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
