"""Fixtures for the record / Foxglove tests: short runs, a calibration, a daemon on a
virtual CAN bus publishing on a loopback Zenoh port."""

from __future__ import annotations

import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from gyrotherm.codecs import Run
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.daemon import Daemon, parse_config
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs
from streamkit import free_port

TIMEOUT_S = 20.0


@pytest.fixture(scope="module")
def runs() -> list[Run]:
    return chamber_runs([5, 20], seed=8, rate_hz=1.0, hold_s=600)


@pytest.fixture(scope="module")
def calibration(runs: list[Run]) -> Calibration:
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    return fit([features(r, est) for r in runs], "paper", estimator=est)


@pytest.fixture()
def daemon(tmp_path: Path, calibration: Calibration) -> Iterator[tuple[str, int]]:
    channel, port = f"rec-{uuid.uuid4().hex[:8]}", free_port()
    cfg = parse_config({
        "vehicle": "testcar", "sensor": "imu0",
        "calibration": str(calibration.save(tmp_path / "cal.json")), "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
    }, base_dir=tmp_path)  # fmt: skip
    d = Daemon(cfg)
    thread = threading.Thread(target=d.run, daemon=True)
    thread.start()
    assert d.ready.wait(TIMEOUT_S)
    yield channel, port
    d.stop()
    thread.join(TIMEOUT_S)
