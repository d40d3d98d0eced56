"""Real exports read without ``--columns`` (PX4 ulog2csv) or with the documented one
(the project's BMI270 CSV); truth from the csv module and the files' SOURCE.md."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import RunFileError
from gyrotherm.readers import InputSpec, parse_columns, read_runs

PX4 = Path(__file__).parent / "data" / "px4-ulog2csv"
#: The project's measured data next to the checkout (README: ../shared), else /work/shared.
_BMI270 = Path("data/measured/bmi270-peltier-laptop/bmi270_static_clean.csv")
BMI270 = next((d / _BMI270 for d in (Path(__file__).resolve().parents[3] / "shared",
                                     Path("/work/shared")) if (d / _BMI270).is_file()),
              Path("/work/shared") / _BMI270)
BMI270_COLUMNS = ("time=t_nominal_s:s temperature=temp_degC:degC x=gyro_x_dps:dps "
                  "y=gyro_y_dps:dps z=gyro_z_dps:dps run=segment")


@pytest.mark.parametrize("instance", [0, 1, 2])
def test_real_px4_ulog2csv_sensor_gyro(instance: int) -> None:
    path = PX4 / f"sample_log_small_sensor_gyro_{instance}.csv"
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    (run,) = read_runs(path, spec=InputSpec())
    assert run.name == path.stem
    assert run.metadata["schema"] == "px4-ulog2csv sensor_gyro"
    assert run.metadata["device_id"] == rows[0]["device_id"]
    # µs since boot from timestamp_sample; rad/s → °/s; °C as logged
    np.testing.assert_allclose(run.time_s, [int(r["timestamp_sample"]) / 1e6 for r in rows],
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.temperature_c, [float(r["temperature"]) for r in rows])
    for axis in "xyz":
        np.testing.assert_allclose(run.rates_dps[axis],
                                   [math.degrees(float(r[axis])) for r in rows], rtol=1e-15)


def test_px4_first_row_by_hand() -> None:
    (run,) = read_runs(PX4 / "sample_log_small_sensor_gyro_0.csv", spec=InputSpec())
    assert run.time_s[0] == pytest.approx(21.311647, abs=1e-12)
    assert run.temperature_c[0] == pytest.approx(40.02537)
    assert run.rates_dps["x"][0] == pytest.approx(-0.04130321 * 57.29577951308232, rel=1e-14)


def _px4_export(path: Path) -> Path:
    """A newer-PX4 sensor_gyro export (clip counters, samples), written with csv."""
    header = ["timestamp", "timestamp_sample", "device_id", "x", "y", "z", "temperature",
              "error_count", "clip_counter[0]", "clip_counter[1]", "clip_counter[2]",
              "samples"]
    rows = [[1000 + 4000 * i, 900 + 4000 * i, 1310988, 0.01 * i, 0.0, -0.02, 35.5 + i, 0,
             0, 0, 0, 1] for i in range(4)]
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


def test_newer_px4_export_and_accel_export_refused(tmp_path: Path) -> None:
    (run,) = read_runs(_px4_export(tmp_path / "flight_sensor_gyro_0.csv"), spec=InputSpec())
    np.testing.assert_allclose(run.time_s, [900e-6, 4900e-6, 8900e-6, 12900e-6], atol=1e-15)
    np.testing.assert_allclose(run.temperature_c, [35.5, 36.5, 37.5, 38.5])
    np.testing.assert_allclose(run.rates_dps["x"], np.degrees([0.0, 0.01, 0.02, 0.03]))
    # sensor_accel has the same header (m/s²): not taken for a gyro
    with pytest.raises(RunFileError, match="cannot tell which columns"):
        read_runs(_px4_export(tmp_path / "flight_sensor_accel_0.csv"), spec=InputSpec())


@pytest.mark.skipif(not BMI270.is_file(), reason="shared measured data not present")
def test_project_bmi270_csv_with_the_documented_columns() -> None:
    runs = read_runs(BMI270, spec=InputSpec(columns=parse_columns(BMI270_COLUMNS.split())))
    assert [r.name for r in runs] == ["bmi270_static_clean:cold", "bmi270_static_clean:hot"]
    assert [len(r) for r in runs] == [3255, 6533]  # SOURCE.md
    # SOURCE.md, "Observed bias": plateau means, dps, and temperatures
    want = {"cold": (13.06, {"x": -0.157, "y": -0.653, "z": -0.253}),
            "hot": (47.58, {"x": 0.503, "y": -0.209, "z": -0.305})}
    for run in runs:
        temp, bias = want[run.metadata["segment"]]
        assert float(np.mean(run.temperature_c)) == pytest.approx(temp, abs=0.005)
        for axis, value in bias.items():
            assert float(np.mean(run.rates_dps[axis])) == pytest.approx(value, abs=0.0006)
        assert run.time_s[1] - run.time_s[0] == pytest.approx(0.02)
