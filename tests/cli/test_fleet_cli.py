"""``gyrotherm fleet`` against simulator truth: five IMUs on three vehicles, calibrated
on one set of logs; in the next logs one IMU's true bias moved by 0.15 °/s (the others
unchanged, new noise and seeds): exactly that IMU is flagged."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleetkit import IMUS, write_fleet
from gyrotherm.cli import main
from gyrotherm.compensation import load_calibration

CHANGED = 3  # veh-b's second IMU


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path], list[Path]]:
    d = tmp_path_factory.mktemp("fleet")
    old = write_fleet(d / "old", heating_min=[10, 30], seed=1)
    new = write_fleet(d / "new", heating_min=[20, 40], seed=2, changed=[CHANGED])
    assert main(["-q", "fleet", *map(str, old), "--out", str(d / "prev")]) == 0
    return d, old, new


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict[str, object]:
    capsys.readouterr()
    assert main(["-q", *argv, "--json"]) == 0
    return dict(json.loads(capsys.readouterr().out))


def test_exactly_the_imu_whose_bias_changed_is_flagged(
        fleet: tuple[Path, list[Path], list[Path]],
        capsys: pytest.CaptureFixture[str]) -> None:
    d, _, new = fleet
    out = _json(capsys, ["fleet", *map(str, new), "--previous", str(d / "prev"),
                         "--out", str(d / "cur")])
    imus = out["imus"]
    assert isinstance(imus, list)
    assert [(i["vehicle_id"], i["device_id"], i["sensor_id"]) for i in imus] == sorted(IMUS)
    flagged = [(i["vehicle_id"], i["device_id"]) for i in imus if i["status"] == "drifted"]
    assert flagged == [IMUS[CHANGED][:2]]
    for imu in imus:
        assert imu["previous"] and Path(imu["previous"]).is_file()
        assert len(imu["runs"]) == 2
        if (imu["vehicle_id"], imu["device_id"]) == IMUS[CHANGED][:2]:
            # truth: +0.15 °/s on x; the fit's constant takes most of it
            assert imu["shift_axis"] == "x" and 0.10 < imu["shift_dps"] < 0.20
            assert imu["residual_axis"] == "x" and 0.10 < imu["residual_dps"] < 0.20
        else:
            assert imu["shift_dps"] < 0.05 / 1.5 and imu["residual_dps"] < 0.05 / 1.5
        assert imu["residual_new_dps"] < 0.02  # the new fit on its own logs: the floor
    # the calibrations written carry the identity: the next run's --previous
    cal = load_calibration(d / "cur" / "veh-b-2490386.json")
    assert {k: cal.provenance[k] for k in ("vehicle_id", "device_id", "sensor_id")} == dict(
        zip(("vehicle_id", "device_id", "sensor_id"), IMUS[CHANGED], strict=True))


def test_the_table_names_the_drifted_imu_and_the_threshold(
        fleet: tuple[Path, list[Path], list[Path]],
        capsys: pytest.CaptureFixture[str]) -> None:
    d, _, new = fleet
    capsys.readouterr()
    assert main(["-q", "fleet", *map(str, new), "--previous", str(d / "prev"),
                 "--jobs", "1"]) == 0
    text = capsys.readouterr().out
    assert "threshold 0.05 °/s" in text
    assert "1 of 5 IMUs drifted: vehicle veh-b, device 2490386 (sensor 2490386)" in text
    assert sum(line.split()[4:5] == ["drifted"] for line in text.splitlines()) == 1
    # a threshold above the change: nothing flagged
    out = _json(capsys, ["fleet", *map(str, new), "--previous", str(d / "prev"),
                         "--threshold-dps", "0.3"])
    assert [i["status"] for i in out["imus"]] == ["ok"] * 5  # type: ignore[union-attr]


def test_without_previous_every_imu_is_new_and_unfittable_ones_are_listed(
        fleet: tuple[Path, list[Path], list[Path]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    _, old, _ = fleet
    short = tmp_path / "short.csv"  # one IMU with a few rows: refused by a quality gate
    short.write_text("\n".join(old[0].read_text().splitlines()[:40]) + "\n")
    text = short.read_text().replace("veh-a", "veh-z")
    short.write_text(text)
    out = _json(capsys, ["fleet", *map(str, old[:4]), str(short)])
    status = {(i["vehicle_id"], i["device_id"]): i["status"] for i in out["imus"]}  # type: ignore[union-attr]
    assert status == {("veh-a", "2490378"): "new", ("veh-a", "2490386"): "new",
                      ("veh-z", "2490378"): "not fitted"}
    refused = next(i for i in out["imus"] if i["status"] == "not fitted")  # type: ignore[union-attr]
    assert "quality gate" in refused["reason"] and refused["calibration"] is None
