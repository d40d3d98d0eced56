"""The daemon speaks sd_notify: READY=1 once bus and Zenoh are up, WATCHDOG=1 from the
processing loop, STATUS= lines, RELOADING=1 then READY=1 on reload, STOPPING=1 at exit."""

from __future__ import annotations

import socket
import threading
import uuid
from pathlib import Path

from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, Notifier, parse_config
from streamkit import free_port

TIMEOUT_S = 20.0


def _recv_until(sock: socket.socket, key: str, got: list[str]) -> bool:
    sock.settimeout(TIMEOUT_S)
    while True:
        try:
            data = sock.recv(4096).decode()
        except TimeoutError:
            return False
        got.append(data)
        if key in data.splitlines():
            return True


def test_notify_protocol(tmp_path: Path, stream_calibration: Calibration) -> None:
    path = tmp_path / "notify.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(str(path))
        cfg = parse_config({
            "vehicle": "nv", "sensor": "imu0",
            "calibration": str(stream_calibration.save(tmp_path / "cal.json")),
            "health_period_s": 0.1,
            "can": {"interface": "virtual", "channel": f"n-{uuid.uuid4().hex[:8]}",
                    "recv_timeout_s": 0.02},
            "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"]},
        })
        notifier = Notifier(str(path), watchdog_interval_s=0.2)
        daemon = Daemon(cfg, notifier=notifier)
        thread = threading.Thread(target=daemon.run, daemon=True)
        thread.start()
        got: list[str] = []
        assert _recv_until(sock, "READY=1", got), got
        assert daemon.ready.is_set()  # READY=1 only after bus and session are up
        assert any(line.startswith("STATUS=") for msg in got for line in msg.splitlines())
        # the loop pets the watchdog repeatedly, with no frames arriving
        assert _recv_until(sock, "WATCHDOG=1", got)
        assert _recv_until(sock, "WATCHDOG=1", got)
        daemon.request_reload()
        assert _recv_until(sock, "RELOADING=1", got)
        assert _recv_until(sock, "READY=1", got)
        daemon.stop()
        assert _recv_until(sock, "STOPPING=1", got)
        thread.join(TIMEOUT_S)
        assert not thread.is_alive()
    assert daemon.reloads == 1 and notifier.send_failures == 0
