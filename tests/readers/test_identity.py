"""Which physical IMU and vehicle a log's runs are: the readers' ``sensor_id`` /
``vehicle_id`` against pyulog and pymavlink, and the CLI's use of them (fit never pools
two vehicles by accident; evaluate and export use only the calibration's IMU)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from pymavlink.DFReader import DFFormat
from pyulog import ULog

import dataflashkit as dk
from gyrotherm import CalibrationError, ConfigError
from gyrotherm.cli import main
from gyrotherm.cli._identity import check_vehicles, matching_runs, recorded
from gyrotherm.codecs import Run
from gyrotherm.readers._dataflash import read_dataflash
from gyrotherm.readers._ulog import read_ulog

DATA = Path(__file__).resolve().parents[1] / "data"
PARM = DFFormat(0x90, "PARM", 0, "QNf", "TimeUS,Name,Value")
MSG = DFFormat(0x91, "MSG", 0, "QZ", "TimeUS,Message")
UID = "0034005A 4E4E5005 20363553"  # the form of a real boot message (corpus plane log)


def _log(path: Path, uid: str | None, gyr_ids: tuple[int, int] = (2162954, 2163210)) -> Path:
    msgs: list[tuple[DFFormat, list[object]]] = [
        (PARM, [1000, b"INS_GYR_ID", float(gyr_ids[0])]),
        (PARM, [1000, b"INS_GYR2_ID", float(gyr_ids[1])]),
        (PARM, [1000, b"SYSID_THISMAV", 1.0]),
        (MSG, [1500, b"ArduCopter V4.5.7 (abcdef12)"]),
    ]
    if uid is not None:
        msgs.append((MSG, [1600, f"omnibusf4pro {uid}".encode()]))
    for t, i, gx, gy, gz, ax, ay, az, temp in dk.SAMPLES:
        msgs.append((dk.IMU, [t, i, gx, gy, gz, ax, ay, az, 0, 0, temp, 1, 1, 400, 400]))
    path.write_bytes(dk.log([PARM, MSG, dk.IMU], msgs))
    return path


def test_dataflash_identity_matches_pymavlink(tmp_path: Path) -> None:
    from pymavlink import mavutil

    path = _log(tmp_path / "a.bin", UID)
    runs = read_dataflash(path)
    m = mavutil.mavlink_connection(str(path))
    params, texts = {}, []
    while (x := m.recv_match(type=["PARM", "MSG"])) is not None:
        if x.get_type() == "PARM":
            params[x.Name] = x.Value
        else:
            texts.append(x.Message)
    assert [r.metadata["sensor_id"] for r in runs] == [
        str(int(params["INS_GYR_ID"])), str(int(params["INS_GYR2_ID"]))]
    board, *uid = texts[-1].split()
    assert {r.metadata["vehicle_id"] for r in runs} == {"ardupilot-uid:" + "".join(uid)}
    assert {r.metadata["board"] for r in runs} == {board}
    no_uid = read_dataflash(_log(tmp_path / "b.bin", None))
    assert {r.metadata["vehicle_id"] for r in no_uid} == {""}  # SYSID_THISMAV is not used


def test_px4_vehicle_is_sys_uuid() -> None:
    path = DATA / "px4_sample_log_small_imu.ulg"
    uuid = ULog(str(path)).msg_info_dict["sys_uuid"]
    runs = read_ulog(path)
    assert {r.metadata["vehicle_id"] for r in runs} == {f"px4-uuid:{uuid}"}
    assert all(r.metadata["sensor_id"] == r.metadata["device_id"] for r in runs)


@pytest.mark.skipif(not (Path(os.environ.get("GYROTHERM_REALLOGS", "")) / "ardupilot"
                         / "plane_center_0003.bin").exists(),
                    reason="real-log corpus not found (GYROTHERM_REALLOGS); a real "
                           "ArduPlane log's boot message and INS_GYR_ID")
def test_identity_of_a_real_ardupilot_log() -> None:
    from gyrotherm.readers._dataflash import _open, identity

    path = Path(os.environ["GYROTHERM_REALLOGS"]) / "ardupilot" / "plane_center_0003.bin"
    log = _open(path)
    try:
        ident = identity(path, log)
    finally:
        log.close()
    assert ident["vehicle_id"] == "ardupilot-uid:0034005A4E4E500520363553"
    assert ident["board"] == "omnibusf4pro" and ident["sensor_id:INS_GYR_ID"] == "2162954"


def _run(name: str, **meta: str) -> Run:
    import numpy as np

    return Run(name=name, time_s=np.arange(3.0), temperature_c=np.zeros(3),
               rates_dps={"x": np.zeros(3)}, metadata=meta)


def test_matching_runs_and_vehicles() -> None:
    a0 = _run("a0", device_id="IMU[0]", sensor_id="1", vehicle_id="v1")
    a1 = _run("a1", device_id="IMU[1]", sensor_id="2", vehicle_id="v1")
    b0 = _run("b0", device_id="IMU[0]", sensor_id="1", vehicle_id="v2")
    plain = _run("csv")
    prov = {"device_id": "IMU[0]", "sensor_id": "1", "vehicle_id": "v1"}
    assert [r.name for r in matching_runs(prov, [a0, a1, b0, plain], what="c")] == ["a0", "csv"]
    with pytest.raises(CalibrationError, match=r"c: no run of the calibration's IMU "
                       r"\(device_id=IMU\[0\] sensor_id=1 vehicle_id=v1\)"):
        matching_runs(prov, [a1, b0], what="c")
    assert matching_runs({}, [a1, b0], what="c") == [a1, b0]
    with pytest.raises(ConfigError, match=r"device 'IMU\[0\]' is on 2 vehicles: v1 .*; v2"):
        check_vehicles([a0, b0], pool=False)
    check_vehicles([a0, b0], pool=True)
    check_vehicles([a0, a1, plain], pool=False)
    assert recorded([a0]) == {"sensor_id": "1", "vehicle_id": "v1"}
    assert recorded([a0, b0]) == {"sensor_id": "1"}


def test_fit_refuses_two_vehicles_unless_asked(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    a = _log(tmp_path / "veh-a.bin", UID)
    b = _log(tmp_path / "veh-b.bin", "0034005A 4E4E5005 20363554")
    assert main(["fit", str(a), str(b), "--out", str(tmp_path / "cals")]) == 2
    err = capsys.readouterr().err
    assert "device 'IMU[0]' is on 2 vehicles: ardupilot-uid:0034005A4E4E500520363553" in err
    assert "--pool-vehicles" in err
    main(["fit", str(a), str(b), "--out", str(tmp_path / "cals"), "--pool-vehicles"])
    assert "is on 2 vehicles" not in capsys.readouterr().err  # pooled (6 rows: gated later)


@pytest.mark.parametrize(("param", "value", "message"), [
    (b"AHRS_ORIENTATION", 2.0, r"AHRS_ORIENTATION = 2: ArduPilot logs the IMU rates in the "
     r"body frame"),
    (b"INS_TCAL1_ENABLE", 1.0, r"INS_TCAL1_ENABLE = 1: the logged rates are already "
     r"corrected"),
])
def test_rotated_or_corrected_ardupilot_rates_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], param: bytes, value: float,
        message: str) -> None:
    import re

    path = _log(tmp_path / "a.bin", UID)
    extra = dk.log([PARM], [(PARM, [900, param, value])])
    # the same log with one more PARM: formats first, then the messages of both
    body = path.read_bytes()
    path.write_bytes(body + extra[len(dk.log([PARM], [])):])
    runs = read_dataflash(path)
    key = "ahrs_orientation" if param == b"AHRS_ORIENTATION" else "tcal_enable"
    assert runs[0].metadata[key] == str(int(value))
    assert main(["fit", str(path), "--out", str(tmp_path / "c.json"), "--force"]) == 2
    assert re.search(message, capsys.readouterr().err)
    ok = read_dataflash(_log(tmp_path / "b.bin", UID))
    assert (ok[0].metadata["ahrs_orientation"], ok[0].metadata["tcal_enable"]) == ("", "")


def test_device_selects_an_imu_and_diagnose_wants_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = DATA / "ardupilot_two_imus.bin"
    out = tmp_path / "imp"
    assert main(["-q", "import", str(log), "--out", str(out), "--device", "IMU[1]"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ardupilot_two_imus-IMU_1_.csv"]
    assert main(["-q", "import", str(log), "--out", str(out), "--device", "IMU[7]"]) == 2
    assert "--device IMU[7]: no such device in the inputs; they hold 'IMU[0]', 'IMU[1]'" in \
        capsys.readouterr().err
    assert main(["-q", "diagnose", str(log), "--rest", "all"]) == 2
    assert "diagnose models one gyro; these runs are of 2 IMUs (IMU[0], IMU[1])" in \
        capsys.readouterr().err
