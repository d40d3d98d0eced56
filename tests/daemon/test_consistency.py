"""Consistency of several IMUs: the statistic on synthetic data, the wire format, and a
daemon with two simulated gyros on one bus where one gets a bias step."""

from __future__ import annotations

import dataclasses
import math
import random
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import zenoh

from gyrotherm._zenoh import session_config
from gyrotherm.bus import open_bus
from gyrotherm.codecs._wire_consistency import (
    ConsistencyFlags,
    ConsistencyMessage,
    decode_consistency,
    encode_consistency,
)
from gyrotherm.compensation import features, fit
from gyrotherm.daemon import ConsistencyConfig, Daemon, parse_vehicle_config
from gyrotherm.daemon._consistency import Consistency
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import ChamberProfile, GyroParams, chamber_runs, simulate
from gyrotherm.sim._gyros import gyro_params, several_gyros
from gyrotherm.sim._stream import play
from streamkit import free_port

CFG = ConsistencyConfig()  # window 0.5 s, tolerance 0.1 °/s, 4 σ
#: A step is flagged within two windows and one housekeeping period (module docstring).
DETECT_WITHIN_S = 2 * CFG.window_s + 0.25


def _feed(c: Consistency, t0: float, t1: float, rate_hz: float, step_at_s: float,
          step_dps: float, rng: random.Random,
          silent: int | None = None) -> list[ConsistencyMessage]:
    taps = [c.tap(i) for i in range(len(c.sensors))]
    out: list[ConsistencyMessage] = []
    n = int((t1 - t0) * rate_hz)
    for i in range(n):
        t = t0 + i / rate_hz
        motion = 20.0 * math.sin(t)  # the vehicle turns: both IMUs see it
        for k, tap in enumerate(taps):
            if k == silent:
                continue
            step = step_dps if (k == 1 and t >= step_at_s) else 0.0
            tap(t + 1e-4 * k, motion + rng.gauss(0, 0.2) + step,
                rng.gauss(0, 0.2) - motion, 0.01 * k + rng.gauss(0, 0.2))
        out.extend(c.poll(t))
    return out


def test_healthy_pairs_agree_and_a_step_is_named_in_time() -> None:
    c = Consistency(("imu0", "imu1", "imu2"), CFG)
    msgs = _feed(c, 0.0, 10.0, 1000.0, 6.0, 0.3, random.Random(1))
    before = [m for m in msgs if m.receive_time_s < 6.0]
    assert before and all(m.consistent and m.samples >= 400 for m in before)
    after = [m for m in msgs if m.receive_time_s >= 6.0 and not m.consistent]
    assert {(m.sensor_a, m.sensor_b, m.axes) for m in after} == {("imu0", "imu1", "x"),
                                                                ("imu1", "imu2", "x")}
    first = min(m.receive_time_s for m in after if m.sensor_b == "imu1")
    assert first - 6.0 <= DETECT_WITHIN_S
    late = [m for m in msgs if m.receive_time_s >= 6.0 + DETECT_WITHIN_S]
    assert all(m.consistent == ("imu1" not in (m.sensor_a, m.sensor_b)) for m in late)
    flagged = late[0] if late[0].sensor_b == "imu1" else late[1]
    assert abs(flagged.mean_dps[0] + 0.3) < 0.05  # a − b = −step (imu1 is b)


def test_a_silent_imu_gives_no_data() -> None:
    c = Consistency(("imu0", "imu1"), CFG)
    msgs = _feed(c, 0.0, 2.0, 500.0, 99.0, 0.0, random.Random(2), silent=1)
    assert msgs and all(m.flags == ConsistencyFlags.NO_DATA and m.samples == 0 for m in msgs)


def test_wire_round_trip() -> None:
    m = ConsistencyMessage(7, 1.7e9, 0.5, "imu0", "imu1", 500, (0.3, -0.01, 0.0),
                           (0.01, 0.01, 0.02), (0.14, 0.14, 0.18),
                           ConsistencyFlags.X)
    payload = encode_consistency(m)
    assert payload[:3] == bytes([0xDC, 0x00, 18])  # array16 of 18 elements
    assert decode_consistency(payload) == m and m.axes == "x" and not m.consistent


def test_daemon_flags_a_bias_step_in_one_of_two_simulated_imus(tmp_path: Path) -> None:
    """Two simulated gyros (own physics, seeds, ids; each its own fitted calibration) on
    one virtual bus at 200 Hz, real time: consistent, until 0.5 °/s is added to gyro 1's x
    rate at 3 s: pair imu0/imu1, axis x, flagged within DETECT_WITHIN_S."""
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    tables, runs = [], []
    for k in range(2):
        fitted = chamber_runs([5, 20, 60], seed=8 + k, rate_hz=1.0, hold_s=1200,
                              gyro=gyro_params(k))
        cal = fit([features(r, est) for r in fitted], "paper", estimator=est)
        tables.append({"sensor": f"imu{k}", "calibration": str(cal.save(tmp_path / f"c{k}.json")),
                       "signals": {"rate_frame_id": 0x120 + 2 * k,
                                   "temperature_frame_id": 0x121 + 2 * k}})
        run = simulate(ChamberProfile.from_pairs([(0.0, 20.0), (6.0, 20.0)]), name=f"g{k}",
                       gyro=gyro_params(k), rate_hz=200.0, seed=40 + k)
        runs.append(run)
    step_s = 3.0
    x = runs[1].rates_dps["x"]
    runs[1] = dataclasses.replace(runs[1], rates_dps={
        **runs[1].rates_dps, "x": np.where(runs[1].time_s >= step_s, x + 0.5, x)})
    channel, port = f"cons-{uuid.uuid4().hex[:8]}", free_port()
    daemon = Daemon(parse_vehicle_config({
        "vehicle": "car", "health_period_s": 0.25, "imu": tables,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}, base_dir=tmp_path))
    thread = threading.Thread(target=daemon.run, daemon=True)
    thread.start()
    got: list[ConsistencyMessage] = []
    arrived = threading.Event()
    assert daemon.ready.wait(20.0)
    try:
        with zenoh.open(session_config(connect=[f"tcp/127.0.0.1:{port}"])) as session:
            def on_sample(sample: zenoh.Sample) -> None:
                got.append(decode_consistency(sample.payload.to_bytes()))
                arrived.set()

            sub = session.declare_subscriber("gyrotherm/car/consistency/**", on_sample)
            assert arrived.wait(20.0)
            with open_bus(interface="virtual", channel=channel) as bus:
                t_start = time.time()
                play(several_gyros(runs), bus, speed=1.0)
            sub.undeclare()
    finally:
        daemon.stop()
        thread.join(20.0)
    step_wall = t_start + step_s - float(runs[0].time_s[0])
    played = [m for m in got if t_start + 0.5 <= m.receive_time_s - m.window_s
              and m.receive_time_s <= t_start + float(runs[0].time_s[-1])]
    assert all((m.sensor_a, m.sensor_b) == ("imu0", "imu1") for m in got)
    before = [m for m in played if m.receive_time_s < step_wall]
    assert len(before) >= 3 and all(m.consistent for m in before), before
    flagged = [m for m in played if not m.consistent]
    assert flagged and {m.axes for m in flagged} == {"x"}, flagged
    assert min(m.receive_time_s for m in flagged) - step_wall <= DETECT_WITHIN_S
    assert all(m.flags & ConsistencyFlags.X for m in played
               if m.receive_time_s - m.window_s >= step_wall + 0.05)
