"""The daemon's calibration load: the recorded IMU against the configured device_id."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest

from gyrotherm import CalibrationError, ConfigError
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import parse_config
from gyrotherm.daemon._calload import load_daemon_calibration


def _with_device(cal: Calibration, path: Path, device: str | None) -> Path:
    doc = json.loads(cal.save(path).read_text())
    doc["provenance"].pop("device_id", None)
    if device is not None:
        doc["provenance"]["device_id"] = device
    path.write_text(json.dumps(doc))
    return path


def test_device_id_refuse_warn_and_unrecorded(
        tmp_path: Path, stream_calibration: Calibration,
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gyrotherm.daemon")
    other = _with_device(stream_calibration, tmp_path / "other.json", "IMU[1]")
    mine = _with_device(stream_calibration, tmp_path / "mine.json", "IMU[0]")
    none = _with_device(stream_calibration, tmp_path / "none.json", None)
    with pytest.raises(CalibrationError, match=r"other.json: field 'provenance.device_id' = "
                       r"'IMU\[1\]' is not this sensor's device_id = 'IMU\[0\]'.*refused"):
        load_daemon_calibration(other, device_id="IMU[0]")
    cal, _ = load_daemon_calibration(other, device_id="IMU[0]", device_mismatch="warn")
    assert cal.provenance["device_id"] == "IMU[1]"
    assert "used anyway (device_mismatch = \"warn\")" in caplog.text
    assert load_daemon_calibration(mine, device_id="IMU[0]")[0].provenance["device_id"] == \
        "IMU[0]"
    load_daemon_calibration(none, device_id="IMU[0]")
    assert "none.json records no device" in caplog.text
    load_daemon_calibration(other, device_id=None)  # nothing configured: nothing compared


def test_device_keys_in_the_config() -> None:
    base = {"vehicle": "v", "sensor": "s", "can": {"interface": "virtual", "channel": "c"},
            "zenoh": {"listen": []}}
    cfg = parse_config({**base, "device_id": "2490378"})
    assert (cfg.device_id, cfg.device_mismatch) == ("2490378", "refuse")
    assert parse_config({**base, "device_mismatch": "warn"}).device_mismatch == "warn"
    with pytest.raises(ConfigError, match=r"g.toml: device_mismatch 'ignore' is not"):
        parse_config({**base, "device_mismatch": "ignore"}, source="g.toml")
