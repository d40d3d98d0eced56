"""The arming state the readers put in ``Run.extra["armed"]``, against pyulog's and
pymavlink's own decoding of the same messages (PX4 ``vehicle_status.arming_state``,
ArduPilot ``ARM.ArmState`` and ``EV`` 10/11), held onto the IMU rows here with a plain
loop, and against the generator's truth (tests/flightkit.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dataflashkit as dfk
import flightkit as fk
from gyrotherm.readers import InputSpec, read_runs

DATA = Path(__file__).resolve().parents[1] / "data"


def _held(t_rows: np.ndarray, t_state: list[float], state: list[bool], before: bool
          ) -> np.ndarray:
    out = []
    for t in t_rows:
        prior = [s for ts, s in zip(t_state, state, strict=True) if ts <= t]
        out.append(prior[-1] if prior else before)
    return np.array(out, dtype=bool)


@pytest.fixture(scope="module")
def short_flight() -> fk.Flight:
    """The generated flight's first 300 s at a fifth of the rows (the loop above is slow)."""
    f = fk.flight()
    keep = (f.time_s < 300.0) & (np.arange(len(f.time_s)) % 5 == 0)
    return fk.Flight(f.time_s[keep], f.rates_dps[keep], f.accel_mps2[keep],
                     f.temperature_c[keep], f.armed[keep])


def test_ulog_vehicle_status_as_pyulog_reads_it(short_flight: fk.Flight, tmp_path: Path) -> None:
    from pyulog import ULog

    path = tmp_path / "f.ulg"
    path.write_bytes(fk.ulog(short_flight))
    (run,) = read_runs(path, spec=InputSpec())
    assert run.metadata["armed"] == "vehicle_status.arming_state"
    (status,) = [d for d in ULog(str(path), ["vehicle_status"]).data_list]
    t_state = list(status.data["timestamp"] * 1e-6)
    state = [int(s) == 2 for s in status.data["arming_state"]]  # ARMING_STATE_ARMED
    want = _held(run.time_s, t_state, state, before=state[0])
    np.testing.assert_array_equal(run.extra["armed"] > 0.5, want)
    np.testing.assert_array_equal(want, short_flight.armed)  # the generator's truth
    assert want.any() and not want.all()


@pytest.mark.parametrize("arming", ["ARM", "EV"])
def test_dataflash_arm_and_ev_as_pymavlink_reads_them(short_flight: fk.Flight, arming: str,
                                                      tmp_path: Path) -> None:
    from pymavlink.DFReader import DFReader_binary

    path = tmp_path / "f.bin"
    path.write_bytes(fk.dataflash(short_flight, arming=arming))
    (run,) = read_runs(path, spec=InputSpec())
    assert run.metadata["armed"] == ("ARM.ArmState" if arming == "ARM" else "EV.Id")
    log = DFReader_binary(str(path))
    t_state, state = [], []
    while (m := log.recv_match(type=arming)) is not None:
        t_state.append(m.TimeUS * 1e-6)
        state.append(m.ArmState == 1 if arming == "ARM" else m.Id == 10)
    log.close()
    assert state[0] is True  # the log starts disarmed: the first message is the arming
    want = _held(run.time_s, t_state, state, before=not state[0])
    np.testing.assert_array_equal(run.extra["armed"] > 0.5, want)
    np.testing.assert_array_equal(want, short_flight.armed)


def test_logs_without_an_arming_state_say_none() -> None:
    for name in ("px4_two_gyros.ulg", "ardupilot_two_imus.bin"):
        for run in read_runs(DATA / name, spec=InputSpec()):
            assert run.metadata["armed"] == "none" and "armed" not in run.extra


def test_ev_events_other_than_arming_are_ignored(tmp_path: Path) -> None:
    """EV carries many events (ids other than 10/11): only arming and disarming count."""
    imu = [(dfk.IMU, [5_000_000 + 10_000 * k, 0, 0.0, 0.0, 0.0, 0.0, 0.0, -9.8, 0, 0,
                      30.0, 1, 1, 400, 400]) for k in range(6)]
    events = [(fk.EV, [5_015_000, 18]), (fk.EV, [5_025_000, 10]), (fk.EV, [5_045_000, 11])]
    order = sorted(imu + events, key=lambda m: int(m[1][0]))
    path = tmp_path / "ev.bin"
    path.write_bytes(dfk.log([dfk.IMU, fk.EV], order))
    (run,) = read_runs(path, spec=InputSpec())
    np.testing.assert_array_equal(run.extra["armed"], [0, 0, 0, 1, 1, 0])
