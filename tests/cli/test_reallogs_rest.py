"""Rest detection on the real logs: no row kept as rest turns faster than 5 °/s or is
logged while the vehicle is armed.

Independent truth: each log's raw gyro rows and arming state as pyulog (PX4) or
pymavlink (ArduPilot) decode them, not gyrotherm's readers. The rows kept are those of
:func:`gyrotherm.cli._fitrest.rest_of`, the one rest decision of ``fit``, ``evaluate``,
``diagnose`` and ``export``, matched to the raw rows by time stamp. The real corpus is
walked when it is present (tests/cli/test_reallogs.py says where), the logs committed in
tests/data always."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import RunFileError
from gyrotherm.cli._fitrest import rest_of
from gyrotherm.readers import InputSpec, read_runs

MAX_RATE_DPS = 5.0
ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"


def corpus_dir() -> Path | None:
    """Where tests/cli/test_reallogs.py finds the corpus (the same candidates)."""
    candidates = [os.environ.get("GYROTHERM_REALLOGS", ""),
                  str(ROOT.parent / "shared" / "data" / "reallogs"),
                  "/work/shared/data/reallogs"]
    return next((Path(c) for c in candidates if c and (Path(c) / "SOURCE.md").is_file()), None)


def _logs() -> list[Path]:
    found = [DATA / "px4_sample_log_small_imu.ulg", DATA / "px4_two_gyros.ulg",
             DATA / "ardupilot_two_imus.bin"]
    real = corpus_dir()
    if real is not None:
        found += sorted(real.glob("px4/*.ulg")) + sorted(real.glob("ardupilot/*.bin"))
    return found


def _raw(path: Path, device: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(time s, |ω| °/s, armed or None) per raw IMU row of the reader's ``device``."""
    if path.suffix == ".ulg":
        from pyulog import ULog

        ulog = ULog(str(path), ["sensor_gyro", "vehicle_status"])
        (g,) = [d for d in ulog.data_list if d.name == "sensor_gyro"
                and f"sensor_gyro{d.multi_id}" == device]
        t = g.data.get("timestamp_sample", g.data["timestamp"]).astype(np.float64) * 1e-6
        rate = np.degrees(np.sqrt(sum(g.data[a].astype(np.float64) ** 2 for a in "xyz")))
        status = [d for d in ulog.data_list if d.name == "vehicle_status"]
        if not status:
            return t, rate, None
        ts = status[0].data["timestamp"] * 1e-6
        state = status[0].data["arming_state"] == 2  # ARMING_STATE_ARMED
        idx = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, None)
        return t, rate, state[idx]
    from pymavlink.DFReader import DFReader_binary

    log = DFReader_binary(str(path))
    rows = []
    while (m := log.recv_match(type="IMU")) is not None:
        if f"IMU[{m.I}]" == device:
            rows.append((m.TimeUS * 1e-6, np.degrees(np.hypot(np.hypot(m.GyrX, m.GyrY),
                                                               m.GyrZ))))
    log.close()
    a = np.array(rows)
    return a[:, 0], a[:, 1], None


@pytest.mark.parametrize("path", _logs(), ids=[p.name for p in _logs()])
def test_no_row_turning_faster_than_5_dps_or_armed_is_kept(path: Path) -> None:
    try:
        runs = read_runs(path, spec=InputSpec())
    except RunFileError as exc:  # no IMU in it (the corpus has such logs): nothing kept
        pytest.skip(f"{path.name}: no IMU rows to keep ({str(exc)[len(str(path)) + 2:][:60]}…)")
    for run in runs:
        kept = rest_of(run).rest
        t, rate, armed = _raw(path, run.metadata["device_id"] if path.suffix == ".bin"
                              else run.name.split(":")[-1])
        row = {float(x): i for i, x in enumerate(t)}  # the raw row of each kept time
        idx = np.array([row[float(x)] for x in run.time_s[kept]], dtype=np.intp)
        assert not np.any(rate[idx] > MAX_RATE_DPS), (run.name, rate[idx].max())
        if armed is not None:
            assert not np.any(armed[idx]), run.name


def test_the_corpus_flying_logs_turn_and_are_armed() -> None:
    """The property above is not vacuous: the corpus holds logs that turn past 5 °/s and
    are armed (pyulog), and such rows are in the runs the readers return."""
    real = corpus_dir()
    if real is None:
        pytest.skip("real-log corpus not found: set GYROTHERM_REALLOGS or place it at "
                    "../shared/data/reallogs (tests/data/REALLOGS.md lists the files)")
    turning = armed = 0
    for path in sorted(real.glob("px4/*.ulg")):
        try:
            runs = read_runs(path, spec=InputSpec())
        except RunFileError:
            continue
        for run in runs:
            _, rate, arm = _raw(path, run.name.split(":")[-1])
            turning += int(np.count_nonzero(rate > MAX_RATE_DPS))
            armed += int(np.count_nonzero(arm)) if arm is not None else 0
    # roboto_fmu_v5: 4 of 10 rows past 5 °/s (up to 214 °/s), 9 armed; sample_log_small:
    # 5 of 6 armed per IMU; sample_px4_events: 15 of 31 armed
    assert turning >= 4 and armed >= 39


def test_real_flights_sensor_combined_keep_no_turning_or_armed_row() -> None:
    """The corpus's PX4 flights that log no ``sensor_gyro`` (no temperature: the readers
    refuse them) still log the rates, at 250 Hz, in ``sensor_combined``: rest detection
    on those rows (pyulog's decoding, with the accelerometer and the arming state) keeps
    none turning past 5 °/s nor armed. sample.ulg flies 69 s at up to 188 °/s."""
    real = corpus_dir()
    if real is None:
        pytest.skip("real-log corpus not found: set GYROTHERM_REALLOGS or place it at "
                    "../shared/data/reallogs (tests/data/REALLOGS.md lists the files)")
    from pyulog import ULog

    from gyrotherm.compensation._rest import RestConfig, detect_rest

    turning = 0
    for path in sorted(real.glob("px4/*.ulg")):
        ulog = ULog(str(path), ["sensor_combined", "vehicle_status"])
        combined = [d for d in ulog.data_list if d.name == "sensor_combined"]
        if not combined:
            continue
        data = combined[0].data
        t = data["timestamp"].astype(np.float64) * 1e-6
        rates = {a: np.degrees(data[f"gyro_rad[{i}]"].astype(np.float64))
                 for i, a in enumerate("xyz")}
        ax, ay, az = (data[f"accelerometer_m_s2[{i}]"].astype(np.float64) for i in range(3))
        status = [d for d in ulog.data_list if d.name == "vehicle_status"]
        armed = None
        if status:
            ts = status[0].data["timestamp"] * 1e-6
            idx = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, None)
            armed = (status[0].data["arming_state"][idx] == 2).astype(np.float64)
        report = detect_rest(t, rates, accel_mps2=(ax, ay, az), armed=armed,
                             config=RestConfig(), name=path.name, short="keep")
        rate = np.sqrt(sum(v**2 for v in rates.values()))
        turning += int(np.count_nonzero(rate > MAX_RATE_DPS))
        assert not np.any(report.rest & (rate > MAX_RATE_DPS)), path.name
        if armed is not None:
            assert not np.any(report.rest & (armed > 0)), path.name
    assert turning > 1000  # sample.ulg alone: 911 rows past 5 °/s
