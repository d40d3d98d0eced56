"""Calibration files refuse keys they do not define, like the TOML config does."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from gyrotherm import CalibrationError
from gyrotherm.compensation import Calibration, RunFeatures, fit, load_calibration
from gyrotherm.compensation._calibration import KNOWN_KEYS, known_keys
from gyrotherm.estimators import EstimatorConfig


@pytest.fixture(scope="module")
def calibration(paper_features: list[RunFeatures], estimator: EstimatorConfig) -> Calibration:
    return fit(paper_features[:3], "paper", estimator=estimator)


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def _with(doc: dict[str, Any], path: str, key: str) -> dict[str, Any]:
    out = json.loads(json.dumps(doc))
    node = out
    for part in path.split(".") if path else ():
        node = node[part]
    node[key] = 1.0
    return out


# (object, typo) → the known keys the message must list, written out here by hand
CASES = [
    ("", "scalling", ["coefficients", "coefficients_physical", "estimator", "model",
                      "provenance", "range", "scaling", "schema", "units", "version"]),
    ("units", "angle", ["bias", "delta_t", "rate", "temperature"]),
    ("model", "order", ["name", "terms"]),
    ("scaling", "t_scale", ["dt_scale_c", "t_ref_c", "t_scale_c"]),
    ("range", "t_min", ["dt_max_c", "dt_min_c", "t_max_c", "t_min_c"]),
    ("coefficients_physical", "w", ["x", "y", "z"]),
]


@pytest.mark.parametrize(("where", "key", "known"), CASES)
def test_an_unknown_key_names_file_key_and_known_keys(
    calibration: Calibration, tmp_path: Path, where: str, key: str, known: list[str]
) -> None:
    path = _write(tmp_path, _with(calibration.to_dict(), where, key))
    place = f"field '{where}'" if where else "the top level"
    with pytest.raises(CalibrationError) as err:
        load_calibration(path)
    assert str(err.value) == (f"{path}: unknown key(s) ['{key}'] in {place}; "
                              f"known: {known!r}")


def test_several_unknown_keys_are_named_together(
    calibration: Calibration, tmp_path: Path
) -> None:
    doc = _with(_with(calibration.to_dict(), "", "zeta"), "", "alpha")
    with pytest.raises(CalibrationError, match=re.escape("unknown key(s) ['alpha', 'zeta']")):
        load_calibration(_write(tmp_path, doc))


def test_unknown_estimator_field_lists_the_known_ones(
    calibration: Calibration, tmp_path: Path
) -> None:
    doc = _with(calibration.to_dict(), "estimator", "tau")
    with pytest.raises(CalibrationError) as err:
        load_calibration(_write(tmp_path, doc))
    msg = str(err.value)
    assert msg.startswith(str(tmp_path / "cal.json"))
    assert "unknown field(s) ['tau']" in msg and "'tau_s'" in msg and "'stale_after_s'" in msg


def test_provenance_stays_open_and_written_files_load(
    calibration: Calibration, tmp_path: Path
) -> None:
    doc = calibration.to_dict()
    doc["provenance"]["operator"] = "bench 3"  # free-form by design
    back = load_calibration(_write(tmp_path, doc))
    assert back.provenance["operator"] == "bench 3"
    assert set(calibration.to_dict()) == known_keys(1)[""]  # the writer and the table agree


def test_the_table_is_what_version_1_defines() -> None:
    assert known_keys(1) == {path: frozenset(keys) for path, keys in KNOWN_KEYS.items()}


def test_keys_of_a_later_version_are_unknown_to_an_earlier_one(
    calibration: Calibration, tmp_path: Path
) -> None:
    doc = calibration.to_dict()
    assert doc["version"] == 1
    doc["effects"] = {a: {} for a in calibration.axes}  # a version 2 block in a version 1 file
    with pytest.raises(CalibrationError, match=re.escape("unknown key(s) ['effects'] in the "
                                                         "top level")):
        load_calibration(_write(tmp_path, doc))
    assert {"effects", "runtime_state"} <= known_keys(2)[""]
    assert "time" in known_keys(2)["units"] and "time" not in known_keys(1)["units"]
