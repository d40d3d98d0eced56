"""The daemon runs version-1 and version-2 calibrations (effects), at start and on
reload; a file of an unknown version is still refused naming the file and field.
Parity of the rates with offline compensation: test_effects_daemon.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrotherm import CalibrationError
from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
from gyrotherm.analysis._to_calibration import calibration_from_models
from gyrotherm.codecs import FrameDecoder
from gyrotherm.compensation import Scaling, ValidRange
from gyrotherm.daemon import Daemon, Pipeline, parse_config
from gyrotherm.estimators import EstimatorConfig
from streamkit import RecordingSink

SCALING = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=8.0)


def _write(path: Path, effects: dict[str, float], columns: tuple[str, ...],
           coefficients: tuple[float, ...]) -> Path:
    model = ExtendedModel(SCALING, effects, columns, coefficients, intercept_dps=0.3)
    cal = calibration_from_models({"x": model}, estimator=EstimatorConfig(), t_on_max_s=3600.0,
                                  valid_range=ValidRange(-40.0, 85.0, -10.0, 10.0),
                                  provenance={"method": "by hand"})
    return cal.save(path)


def _config(cal: Path) -> dict[str, object]:
    return {"vehicle": "v", "sensor": "s", "calibration": str(cal),
            "can": {"interface": "virtual", "channel": "versions"},
            "zenoh": {"listen": []}}


def test_version_2_runs_at_start_and_on_reload(tmp_path: Path) -> None:
    cal = _write(tmp_path / "v2.json", {"warmup": 400.0}, (*BASE_COLUMNS, "warmup"),
                 (0.02, -0.05, 0.03, 0.004, 0.1))
    daemon = Daemon(parse_config(_config(cal)))
    assert daemon._calibration is not None and daemon._calibration.version == 2
    pipe = Pipeline(FrameDecoder(), RecordingSink(), calibration=daemon._calibration)
    daemon._do_reload(pipe)
    assert daemon.reloads == 1 and daemon.reload_failures == 0
    assert pipe.calibration is not None and pipe.calibration.effect_names("x") == ("warmup",)


def test_an_unknown_version_is_still_refused_naming_file_and_field(tmp_path: Path) -> None:
    cal = _write(tmp_path / "v7.json", {}, BASE_COLUMNS, (0.02, -0.05, 0.03, 0.004))
    doc = json.loads(cal.read_text())
    doc["version"] = 7
    cal.write_text(json.dumps(doc))
    with pytest.raises(CalibrationError, match=r"v7\.json: field 'version'"):
        Daemon(parse_config(_config(cal)))


def test_version_1_paper_calibration_is_accepted(tmp_path: Path) -> None:
    cal = _write(tmp_path / "v1.json", {}, BASE_COLUMNS, (0.02, -0.05, 0.03, 0.004))
    daemon = Daemon(parse_config(_config(cal)))
    assert daemon._calibration is not None and daemon._calibration.version == 1
