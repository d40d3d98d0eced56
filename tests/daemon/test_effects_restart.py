"""A real daemon (in process: virtual CAN → Daemon → Zenoh → Subscriber) with a
version-2 calibration and ``state_dir``, stopped mid-run and started again: the state
file written at shutdown is restored, and the corrected rates of both runs equal the
offline compensator over their estimator output as one series from power-on."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gyrotherm.codecs import Run
from gyrotherm.compensation import Calibration
from streamkit import make_v2, offline_bias, restart_setup, run_daemon_in_process


def test_restart_restores_the_effects_state(
    tmp_path: Path, short_runs: list[Run], stream_calibration: Calibration
) -> None:
    v2 = make_v2(stream_calibration)
    cal_path = v2.save(tmp_path / "v2.json")
    run = short_runs[2].slice(0, 1200)
    frames, channel, port, cfg = restart_setup(tmp_path, cal_path, run, "eff")
    cut = 700
    r1, s1, sum1 = run_daemon_in_process(cfg, tmp_path, frames[:2 * cut], channel, port, cut)
    saved = json.loads((tmp_path / "state" / "car.imu0.effects-state.json").read_text())
    assert saved["time_s"] == run.time_s[cut - 1] and saved["power_on_s"] == run.time_s[0]
    r2, s2, sum2 = run_daemon_in_process(cfg, tmp_path, frames[2 * cut:], channel, port,
                                         len(run) - cut)
    assert sum1.drops == {} and sum2.drops == {}
    states = s1 + s2
    assert len(states) == len(run) and len(r1 + r2) == len(run)
    assert s2[0].effects["x"].t_on_s == run.time_s[cut] - run.time_s[0]  # restored
    ref = offline_bias(v2, np.array([s.sensor_time_s for s in states]),
                       np.array([s.temperature_c for s in states]),
                       np.array([s.delta_t_c for s in states]))
    rates = np.array([r.rate_dps for r in r1 + r2])
    for j, axis in enumerate("xyz"):
        np.testing.assert_allclose(rates[:, j], run.rates_dps[axis] - ref[axis], atol=1e-9)
