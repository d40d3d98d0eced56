"""Several IMUs in one configuration: [[imu]] tables, their errors, the one-IMU file unchanged."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gyrotherm import ConfigError
from gyrotherm.daemon import (
    ConsistencyConfig,
    load_config,
    load_vehicle_config,
    parse_config,
    parse_vehicle_config,
)

DEPLOY = Path(__file__).resolve().parents[2] / "deploy" / "config"


def _doc(*imus: dict[str, object], **top: object) -> dict[str, object]:
    return {"vehicle": "veh01", "can": {"interface": "virtual", "channel": "c"},
            "zenoh": {"listen": ["tcp/127.0.0.1:7447"]}, **top, "imu": list(imus)}


IMU0 = {"sensor": "imu0"}
IMU1 = {"sensor": "imu1", "signals": {"rate_frame_id": 0x122, "temperature_frame_id": 0x123}}
IMU2 = {"sensor": "imu2", "signals": {"rate_frame_id": 0x124, "temperature_frame_id": 0x125},
        "calibration": "cal2.json", "device_id": "42", "listen": ["tcp/127.0.0.1:7450"]}


def test_one_imu_files_read_unchanged() -> None:
    for path in sorted(DEPLOY.glob("gyrotherm*.toml")):
        vehicle = load_vehicle_config(path)
        assert not vehicle.multi and vehicle.consistency is None
        assert vehicle.imus == (load_config(path),)


def test_shipped_multi_imu_example() -> None:
    vehicle = load_vehicle_config(DEPLOY / "gyrotherm-3imu.toml.example")
    assert vehicle.multi and vehicle.sensors == ("imu0", "imu1", "imu2")
    assert vehicle.consistency == ConsistencyConfig()


def test_imu_tables_share_the_rest(tmp_path: Path) -> None:
    v = parse_vehicle_config(_doc(IMU0, IMU1, IMU2, health_period_s=0.5,
                                  consistency={"window_s": 1.0}), base_dir=tmp_path)
    assert v.sensors == ("imu0", "imu1", "imu2") and v.multi
    assert {c.vehicle for c in v.imus} == {"veh01"}
    assert {c.health_period_s for c in v.imus} == {0.5}
    assert {c.can.channel for c in v.imus} == {"c"}
    assert v.imus[0].can.signals.rate_frame_id is None
    assert v.imus[1].can.signals.rate_frame_id == 0x122
    assert v.imus[1].can.signals.rate_message == "GyroRate"  # merged over the shipped map
    assert v.imus[2].calibration == tmp_path / "cal2.json" and v.imus[2].device_id == "42"
    assert v.imus[0].calibration is None and v.imus[0].zenoh.listen == ("tcp/127.0.0.1:7447",)
    assert v.imus[2].zenoh.listen == ("tcp/127.0.0.1:7447",)  # one process: the shared one
    assert v.consistency == ConsistencyConfig(window_s=1.0)
    alone = v.only("imu2")
    assert not alone.multi and alone.consistency is None
    assert alone.imus == (dataclasses.replace(v.imus[2], zenoh=dataclasses.replace(
        v.imus[2].zenoh, listen=("tcp/127.0.0.1:7450",))),)
    with pytest.raises(ConfigError, match=r"--imu 'imu9'.*\['imu0', 'imu1', 'imu2'\]"):
        v.only("imu9")


def test_consistency_off_and_single_table() -> None:
    assert parse_vehicle_config(_doc(IMU0, IMU1, consistency={"enabled": False})).consistency \
        is None
    one = parse_vehicle_config(_doc(IMU0))
    assert one.multi and one.consistency is None and one.sensors == ("imu0",)


@pytest.mark.parametrize(("doc", "message"), [
    (_doc(IMU0, {"signals": {"rate_frame_id": 0x130}}),
     r"\[\[imu\]\] #1: key 'sensor' is required"),
    (_doc(IMU0, {**IMU1, "colour": "red"}), r"\[\[imu\]\] #1: unknown key\(s\) \['colour'\]"),
    (_doc(IMU0, {"sensor": "imu0", "signals": IMU1["signals"]}),
     r"\[\[imu\]\] #1: sensor = 'imu0' is already used"),
    (_doc(IMU0, {"sensor": "imu1"}),
     r"\[\[imu\]\] #1: message 'GyroRate' at frame id 0x120 is also \[\[imu\]\] #0 \(imu0\)'s"),
    (_doc(IMU0, {**IMU1, "device_mismatch": "maybe"}),
     r"\[\[imu\]\] #1: device_mismatch 'maybe' is not 'refuse' or 'warn'"),
    (_doc(IMU0, {**IMU1, "sensor": "a/b"}), r"\[\[imu\]\] #1: sensor name 'a/b' is invalid"),
    (_doc(IMU0, {"sensor": "consistency"}), r"\[\[imu\]\] #1: sensor = 'consistency' is reserved"),
    (_doc(IMU0, {**IMU1, "signals": {"rate_frame_id": 0x900}}),
     r"\[\[imu\]\] #1: .*frame id override 0x900 is above 0x7ff"),
    (_doc(IMU0, {**IMU1, "signals": {"rate_frame_id": "0x122"}}),
     r"\[\[imu\]\] #1.*rate_frame_id must be a CAN id.*'0x122'"),
    (_doc(IMU0, {**IMU1, "listen": ["tcp/0.0.0.0:7447"]}),
     r"\[\[imu\]\] #1: \[zenoh\].*listens on all interfaces"),
    (_doc(IMU0, IMU1, sensor="imu0"), r"sensor = 'imu0' at the top level.*each \[\[imu\]\] table"),
    (_doc(IMU0, IMU1, calibration="x.json"), r"calibration = 'x.json' at the top level"),
    (_doc(IMU0, IMU1, consistency={"window_s": 0.0}),
     r"\[consistency\]: window_s = 0.0 must be a number in \[0.05, 60\]"),
    (_doc(IMU0, IMU1, consistency={"min_samples": 1.5}),
     r"\[consistency\]: min_samples = 1.5 must be an integer"),
    ({**_doc(IMU0), "imu": {"sensor": "imu0"}}, r"imu must be one or more \[\[imu\]\] tables"),
    ({"vehicle": "v", "sensor": "imu0", "consistency": {}}, r"\[consistency\] needs \[\[imu\]\]"),
])
def test_errors_name_the_table_field_and_value(doc: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_vehicle_config(doc, source="veh.toml")


def test_parse_config_points_to_the_vehicle_reader() -> None:
    with pytest.raises(ConfigError, match=r"several IMUs: read it with .*load_vehicle_config"):
        parse_config(_doc(IMU0, IMU1))
