"""End to end in one process: virtual CAN bus → daemon → Zenoh → client Subscriber."""

from __future__ import annotations

import threading
import uuid
from pathlib import Path

import pytest

from gyrotherm.bus import open_bus
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, RunSummary, parse_config
from streamkit import assert_offline_compensation, free_port, run_frames

TIMEOUT_S = 20.0


def _config(tmp_path: Path, channel: str, port: int, calibration: Path) -> dict[str, object]:
    return {
        "vehicle": "testcar", "sensor": "imu0", "calibration": str(calibration),
        "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
    }


@pytest.fixture()
def daemon_env(tmp_path: Path, stream_calibration: Calibration):  # type: ignore[no-untyped-def]
    cal_path = stream_calibration.save(tmp_path / "cal.json")
    channel = f"e2e-{uuid.uuid4().hex[:8]}"
    port = free_port()
    cfg = parse_config(_config(tmp_path, channel, port, cal_path), base_dir=tmp_path)
    daemon = Daemon(cfg)
    result: dict[str, RunSummary] = {}
    thread = threading.Thread(target=lambda: result.update(s=daemon.run()), daemon=True)
    thread.start()
    assert daemon.ready.wait(TIMEOUT_S)
    yield daemon, channel, port, cal_path, result
    daemon.stop()
    thread.join(TIMEOUT_S)


def test_end_to_end_in_one_process(daemon_env, short_runs: list[Run],  # type: ignore[no-untyped-def]
                                   stream_calibration: Calibration) -> None:
    from gyrotherm.client import Subscriber

    daemon, channel, port, _cal_path, result = daemon_env
    run = short_runs[2].slice(0, 600)
    frames = list(run_frames(run, FrameEncoder()))
    with Subscriber("testcar", "imu0", connect=[f"tcp/127.0.0.1:{port}"]) as sub, \
            open_bus(interface="virtual", channel=channel) as bus:
        # the subscriber is connected once a health message arrives
        assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
        for msg in frames:
            bus.send(msg)
        assert sub.wait_for(lambda s: s.rate.received >= len(run), timeout_s=TIMEOUT_S)
        info = sub.query_calibration(timeout_s=5.0)
        rates = list(sub.rates(timeout_s=0.5))
    daemon.stop()
    # every frame accounted for
    summary = None
    for _ in range(100):
        if "s" in result:
            summary = result["s"]
            break
        threading.Event().wait(0.05)
    assert summary is not None
    assert summary.frames_received == len(frames)
    assert summary.frames_published + sum(summary.drops.values()) == summary.frames_received
    assert summary.drops == {}
    # corrected rates equal offline compensation of the same run
    assert [r.seq for r in rates] == list(range(len(run)))
    assert_offline_compensation([r.rate_dps for r in rates], run, stream_calibration)
    assert info.calibration is not None
    assert info.calibration["model"]["name"] == "paper"
    assert info.calibration_id and info.health is not None
    st = sub.stats()
    assert st.rate.gaps == 0 and st.rate.latency.count == len(run)


def test_reload_keeps_old_calibration_on_bad_file(daemon_env) -> None:  # type: ignore[no-untyped-def]
    daemon, _, _, cal_path, _ = daemon_env
    good = cal_path.read_text()
    cal_path.write_text("{ not json")
    daemon.request_reload()
    assert _wait(lambda: daemon.reload_failures == 1)
    assert daemon._calibration is not None  # the old one stays
    cal_path.write_text(good)
    daemon.request_reload()
    assert _wait(lambda: daemon.reloads == 1)


def _wait(predicate, timeout_s: float = TIMEOUT_S) -> bool:  # type: ignore[no-untyped-def]
    ev = threading.Event()
    deadline = 0.0
    while deadline < timeout_s:
        if predicate():
            return True
        ev.wait(0.02)
        deadline += 0.02
    return bool(predicate())
