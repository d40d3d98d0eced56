"""``export`` writes a calibration into its own IMU's slot: ``fit`` records the
instance the log gives the IMU, ``export`` takes the slot from it (INS_TCAL<i+1>,
TC_G<i>), refuses another ``--instance``, and writes ``--vehicle-id`` into the
QGroundControl file's first column (QGC loads a file only onto that system id)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from gyrotherm.cli import main
from gyrotherm.sim import chamber_runs


@pytest.fixture(scope="module")
def two_imus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three heating logs, each with two IMUs (device 7 then 9) interleaved by time."""
    d = tmp_path_factory.mktemp("slots")
    for k, minutes in enumerate((10, 30, 60)):
        a = chamber_runs([minutes], seed=3, rate_hz=1.0, hold_s=900.0)[0]
        b = chamber_runs([minutes], seed=4, rate_hz=1.0, hold_s=900.0)[0]
        with (d / f"log{k}.csv").open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["t", "dev", "temp", "gx", "gy", "gz"])
            for dev, run in (("7", a), ("9", b)):
                for i in range(len(run)):
                    w.writerow([run.time_s[i], dev, run.temperature_c[i],
                                *(run.rates_dps[x][i] for x in "xyz")])
    cols = ["--columns", "time=t:s", "temperature=temp:degC", "x=gx:dps", "y=gy:dps",
            "z=gz:dps", "device=dev"]
    assert main(["-q", "fit", *(str(d / f"log{k}.csv") for k in range(3)), *cols,
                 "--out", str(d / "cal-{device}.json"), "--no-validation"]) == 0
    return d


def test_fit_records_each_imus_instance(two_imus: Path) -> None:
    for dev, instance in (("7", 0), ("9", 1)):
        doc = json.loads((two_imus / f"cal-{dev}.json").read_text())
        assert doc["provenance"]["device_id"] == dev
        assert doc["provenance"]["instance"] == instance


def test_export_takes_the_slot_from_the_calibration(two_imus: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    cal, ap, px4 = two_imus / "cal-9.json", two_imus / "g.param", two_imus / "g.params"
    assert main(["export", str(cal), "--ardupilot", str(ap), "--px4", str(px4),
                 "--device-id", "2359586", "--vehicle-id", "7", "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["instance"] == 1
    names = [line.split(",")[0] for line in ap.read_text().splitlines()
             if line and not line.startswith("#")]
    assert names and all(n.startswith("INS_TCAL2_") for n in names)
    rows = [line.split("\t") for line in px4.read_text().splitlines()
            if line and not line.startswith("#")]
    assert {r[0] for r in rows} == {"7"} and {r[1] for r in rows} == {"1"}
    slot_names = {r[2] for r in rows} - {"TC_G_ENABLE"}
    assert slot_names and all(n.startswith("TC_G1_") for n in slot_names)
    assert ("TC_G1_ID", "2359586") in {(r[2], r[3]) for r in rows}


def test_another_instance_and_a_bad_vehicle_id_are_refused(
        two_imus: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = str(two_imus / "cal-9.json")
    assert main(["export", cal, "--ardupilot", str(two_imus / "x.param"),
                 "--instance", "0"]) == 2
    assert "the calibration is of IMU instance 1 (device '9')" in capsys.readouterr().err
    assert main(["export", cal, "--px4", str(two_imus / "x.params"), "--device-id", "5",
                 "--vehicle-id", "0"]) == 2
    assert "--vehicle-id 0: a MAVLink system id is 1..255" in capsys.readouterr().err
