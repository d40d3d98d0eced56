"""Across processes: simulator serving socketcand → `gyrotherm run` subprocess → Subscriber.

Also: SIGHUP reloads (a bad file keeps the old calibration and says why), SIGTERM
stops cleanly with every frame accounted for.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.compensation import Calibration
from gyrotherm.sim import SocketcandServer
from gyrotherm.sim._stream import frames_from_run, play
from streamkit import assert_offline_compensation, free_port

TIMEOUT_S = 30.0


class _Lines:
    """Collects a subprocess's stderr lines; wait for one matching a pattern."""

    def __init__(self, stream) -> None:  # type: ignore[no-untyped-def]
        self.lines: list[str] = []
        self._cond = threading.Condition()
        threading.Thread(target=self._pump, args=(stream,), daemon=True).start()

    def _pump(self, stream) -> None:  # type: ignore[no-untyped-def]
        for line in stream:
            with self._cond:
                self.lines.append(line)
                self._cond.notify_all()

    def wait_for(self, pattern: str, timeout_s: float = TIMEOUT_S) -> str | None:
        rx = re.compile(pattern)
        with self._cond:
            found = self._cond.wait_for(
                lambda: any(rx.search(x) for x in self.lines), timeout=timeout_s)
            return next((x for x in self.lines if rx.search(x)), None) if found else None


def test_end_to_end_across_processes(tmp_path: Path, short_runs: list[Run],
                                     stream_calibration: Calibration) -> None:
    run = short_runs[1].slice(0, 500)
    cal_path = stream_calibration.save(tmp_path / "cal.json")
    zport = free_port()
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        config = tmp_path / "gyrotherm.toml"
        config.write_text(f"""
vehicle = "proc"
sensor = "imu0"
calibration = "cal.json"
health_period_s = 0.2
[can]
interface = "socketcand"
host = "127.0.0.1"
port = {server.port}
channel = "vcan0"
[zenoh]
listen = ["tcp/127.0.0.1:{zport}"]
""")
        proc = subprocess.Popen(
            [sys.executable, "-m", "gyrotherm", "run", "--config", str(config)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        err = _Lines(proc.stderr)
        try:
            assert err.wait_for(r"INFO gyrotherm.daemon: up:"), err.lines
            assert server.wait_for_clients(1, TIMEOUT_S)
            with Subscriber("proc", "imu0", connect=[f"tcp/127.0.0.1:{zport}"]) as sub:
                assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
                played = play(frames_from_run(run, encoder=FrameEncoder()), server, speed=0)
                assert server.flush(TIMEOUT_S)
                assert sub.wait_for(lambda s: s.rate.received >= played.rate_frames,
                                    timeout_s=TIMEOUT_S)
                rates = list(sub.rates(timeout_s=0.5))
                # SIGHUP with a broken file: the old calibration stays, the log says why
                good = cal_path.read_text()
                cal_path.write_text('{"schema": "gyrotherm.calibration", "version": 7}')
                proc.send_signal(signal.SIGHUP)
                assert err.wait_for(r"calibration reload failed, keeping .*version 7")
                cal_path.write_text(good)
                proc.send_signal(signal.SIGHUP)
                assert err.wait_for(r"calibration reloaded")
                health = sub.wait_for(
                    lambda s: s.health.received >= 3, timeout_s=TIMEOUT_S)
                assert health
            proc.send_signal(signal.SIGTERM)
            out, _ = proc.communicate(timeout=TIMEOUT_S)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 0, err.lines
    # every frame accounted for: published + dropped by reason = received
    m = re.search(r"frames in (\d+), published (\d+), dropped (\d+)", out)
    assert m, out
    received, published, dropped = map(int, m.groups())
    assert received == played.frames_sent
    assert published + dropped == received and dropped == 0
    # the corrected rates equal offline compensation of the same run
    assert [r.seq for r in rates] == list(range(len(run)))
    assert_offline_compensation([r.rate_dps for r in rates], run, stream_calibration)
