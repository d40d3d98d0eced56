"""Three simulated gyros on one socketcand bus → one `gyrotherm run` process with three
[[imu]] tables → three subscribers. One IMU is faulty (it goes silent, its frames fail
the CRC, or its calibration is unusable); the two others must go on exactly as alone:
every rate equal to offline compensation of their simulated run (to 1e-9 °/s), every
frame accounted for per IMU (frames in = published + dropped, nothing dropped), and the
faulty IMU's own accounting and health say what happened to it."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

import can
import pytest

from gyrotherm.client import Subscriber
from gyrotherm.codecs import Run
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, SocketcandServer, chamber_runs
from gyrotherm.sim._gyros import gyro_params, several_gyros
from gyrotherm.sim._stream import play
from streamkit import assert_offline_compensation, free_port, stdout_after_sigterm

TIMEOUT_S = 30.0


class _Lines:
    """A subprocess's stderr lines, collected on a thread; wait for a pattern."""

    def __init__(self, stream) -> None:  # type: ignore[no-untyped-def]
        self.lines: list[str] = []
        self._cond = threading.Condition()
        threading.Thread(target=self._pump, args=(stream,), daemon=True).start()

    def _pump(self, stream) -> None:  # type: ignore[no-untyped-def]
        for line in stream:
            with self._cond:
                self.lines.append(line)
                self._cond.notify_all()

    def wait_for(self, pattern: str, timeout_s: float = TIMEOUT_S) -> bool:
        rx = re.compile(pattern)
        with self._cond:
            return self._cond.wait_for(lambda: any(rx.search(x) for x in self.lines),
                                       timeout=timeout_s)

ROWS, FAULT_ROW = 400, 100
SENSORS = ("imu0", "imu1", "imu2")
FAULTY = 1
IDS = {0x120 + 2 * k + j: k for k in range(3) for j in (0, 1)}


@pytest.fixture(scope="module")
def gyros() -> list[tuple[Run, Calibration]]:
    """Per gyro: a 1 Hz run (its own physics and seed) and a calibration fitted on it."""
    out = []
    for k in range(3):
        params = gyro_params(k)
        est = EstimatorConfig(tau_s=GyroParams().tau_s)
        runs = chamber_runs([5, 20, 60], seed=8 + k, rate_hz=1.0, hold_s=1200, gyro=params)
        cal = fit([features(r, est) for r in runs], "paper", estimator=est)
        run = chamber_runs([20], seed=300 + k, rate_hz=1.0, hold_s=1200,
                           gyro=params)[0].slice(0, ROWS)
        out.append((run, cal))
    return out


def _faulty(frames: list[can.Message], fault: str, t_fault_s: float) -> list[can.Message]:
    out = []
    for msg in frames:
        if IDS[msg.arbitration_id] == FAULTY and msg.timestamp >= t_fault_s:
            if fault == "silent":
                continue
            if fault == "crc":
                msg.data[7] ^= 0x5A
        out.append(msg)
    return out


@pytest.mark.parametrize("fault", ["silent", "crc", "calibration"])
def test_one_faulty_imu_leaves_the_others_exact(tmp_path: Path, fault: str,
                                                gyros: list[tuple[Run, Calibration]]) -> None:
    runs = [run for run, _ in gyros]
    tables = []
    for k, (_, cal) in enumerate(gyros):
        path = cal.save(tmp_path / f"cal{k}.json")
        if fault == "calibration" and k == FAULTY:
            path.write_text('{"schema": "gyrotherm.calibration", "version": 7}')
        ids = f"signals = {{ rate_frame_id = {0x120 + 2 * k}, temperature_frame_id = " \
              f"{0x121 + 2 * k} }}"
        tables.append(f'[[imu]]\nsensor = "{SENSORS[k]}"\ncalibration = "{path.name}"\n{ids}\n')
    frames = _faulty(list(several_gyros(runs)), fault, float(runs[0].time_s[FAULT_ROW]))
    sent = {k: sum(1 for m in frames if IDS[m.arbitration_id] == k) for k in range(3)}
    zport = free_port()
    # silence: paced so that the faulty IMU is silent longer than stale_after_s (5 s)
    speed = 50.0 if fault == "silent" else 0.0
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        config = tmp_path / "gyrotherm.toml"
        config.write_text(f"""
vehicle = "multi"
health_period_s = 0.2
[can]
interface = "socketcand"
host = "127.0.0.1"
port = {server.port}
channel = "vcan0"
[zenoh]
listen = ["tcp/127.0.0.1:{zport}"]
""" + "\n".join(tables))
        proc = subprocess.Popen(
            [sys.executable, "-m", "gyrotherm", "run", "--config", str(config)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        err = _Lines(proc.stderr)
        try:
            assert err.wait_for(r"INFO gyrotherm.daemon: up:"), err.lines
            assert server.wait_for_clients(1, TIMEOUT_S)
            connect = [f"tcp/127.0.0.1:{zport}"]
            subs = [Subscriber("multi", s, connect=connect) for s in SENSORS]
            try:
                for sub in subs:
                    assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
                play(frames, server, speed=speed)
                assert server.flush(TIMEOUT_S)
                for k in (0, 2):
                    assert subs[k].wait_for(lambda s: s.rate.received >= ROWS,
                                            timeout_s=TIMEOUT_S)
                rates = [list(sub.rates(timeout_s=0.5)) for sub in subs]
                healths = [list(sub.healths(timeout_s=0.0)) for sub in subs]
            finally:
                for sub in subs:
                    sub.close()
            out = stdout_after_sigterm(proc, TIMEOUT_S)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 0, err.lines
    # per IMU: frames in = what the bus carried for it = published + dropped
    acc = {m[0]: (int(m[1]), int(m[2]), int(m[3]), m[4]) for m in re.findall(
        r"^(imu\d): frames in (\d+), published (\d+), dropped (\d+) (\{.*\})$", out, re.M)}
    assert set(acc) == set(SENSORS), out
    for k, name in enumerate(SENSORS):
        received, published, dropped, _ = acc[name]
        assert received == sent[k] and published + dropped == received, (name, acc[name])
    for k in (0, 2):  # the healthy ones: nothing lost, the rates exact
        assert acc[SENSORS[k]][2] == 0, acc
        assert [r.seq for r in rates[k]] == list(range(ROWS))
        assert_offline_compensation([r.rate_dps for r in rates[k]], runs[k], gyros[k][1])
        assert not any(r.flags & StatusFlags.NO_CALIBRATION for r in rates[k])
    faulty = acc[SENSORS[FAULTY]]
    if fault == "silent":
        assert faulty[1] == sent[FAULTY] < sent[0] and faulty[2] == 0
        stale = [h for h in healths[FAULTY] if h.flags & StatusFlags.TEMPERATURE_STALE]
        assert stale and stale[-1].frames_received == sent[FAULTY], healths[FAULTY][-3:]
    elif fault == "crc":
        bad = 2 * (ROWS - FAULT_ROW)  # every rate frame and (1 Hz) temperature frame from then
        assert faulty[3] == f"{{'crc_mismatch': {bad}}}" and faulty[1] == sent[FAULTY] - bad
        assert healths[FAULTY][-1].drops == {"crc_mismatch": bad}
    else:
        assert err.wait_for(r"imu1: calibration refused, this IMU runs uncorrected .*version 7")
        assert faulty[2] == 0 and len(rates[FAULTY]) == ROWS
        assert all(r.flags & StatusFlags.NO_CALIBRATION and r.bias_dps == (0.0, 0.0, 0.0)
                   for r in rates[FAULTY])
        assert healths[FAULTY][-1].calibration_id == ""
