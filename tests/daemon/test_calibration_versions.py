"""The daemon runs version-1 calibrations; a version-2 file (effects) is refused at
start and on reload with a message naming the file and the effects, never half-run."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyrotherm import CalibrationError
from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
from gyrotherm.analysis._export import calibration_from_models
from gyrotherm.compensation import Scaling, ValidRange
from gyrotherm.daemon import Daemon, parse_config
from gyrotherm.estimators import EstimatorConfig

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


def test_version_2_is_refused_at_start_naming_file_and_effects(tmp_path: Path) -> None:
    cal = _write(tmp_path / "v2.json", {"warmup": 400.0}, (*BASE_COLUMNS, "warmup"),
                 (0.02, -0.05, 0.03, 0.004, 0.1))
    with pytest.raises(CalibrationError, match=r"v2\.json: calibration version 2 with "
                                               r"effects \{'x': \('warmup',\)\}"):
        Daemon(parse_config(_config(cal)))


def test_version_1_paper_calibration_is_accepted(tmp_path: Path) -> None:
    cal = _write(tmp_path / "v1.json", {}, BASE_COLUMNS, (0.02, -0.05, 0.03, 0.004))
    daemon = Daemon(parse_config(_config(cal)))
    assert daemon._calibration is not None and daemon._calibration.version == 1
