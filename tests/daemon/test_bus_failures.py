"""A bus whose recv raises at run time (a CAN interface gone down) is reopened; the loop
neither dies nor spins, and keeps petting the watchdog meanwhile."""

from __future__ import annotations

import threading
import uuid
from pathlib import Path

import can
import pytest

from gyrotherm.bus import FrameSource
from gyrotherm.daemon import Daemon, parse_config
from streamkit import free_port

TIMEOUT_S = 20.0


class _Source(FrameSource):
    """recv raises ``error`` (counting calls) or waits like a quiet bus."""

    def __init__(self, error: Exception | None) -> None:
        self.error = error
        self.calls = 0
        self.read = threading.Event()
        self._down = threading.Event()

    def recv(self, timeout_s: float | None = None) -> can.Message | None:
        self.calls += 1
        self.read.set()
        if self.error is not None:
            raise self.error
        self._down.wait(timeout_s)
        return None

    @property
    def is_shutdown(self) -> bool:
        return self._down.is_set()

    def shutdown(self) -> None:
        self._down.set()


def test_a_bus_that_raises_is_reopened(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    cfg = parse_config({
        "vehicle": "fail", "sensor": "imu0", "health_period_s": 0.1,
        "can": {"interface": "virtual", "channel": f"f-{uuid.uuid4().hex[:8]}",
                "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{free_port()}"]},
    })
    broken = _Source(can.CanOperationError("Error receiving: Network is down"))
    good = _Source(None)
    sources = iter([broken, good])
    daemon = Daemon(cfg)
    daemon._keeper._open = lambda: next(sources)  # type: ignore[method-assign]
    thread = threading.Thread(target=daemon.run, daemon=True)
    with caplog.at_level("INFO", logger="gyrotherm.daemon"):
        thread.start()
        try:
            assert good.read.wait(TIMEOUT_S), caplog.text  # reopened, now reading
        finally:
            daemon.stop()
            thread.join(TIMEOUT_S)
    assert not thread.is_alive()
    assert daemon.bus_reopens == 1
    assert broken.is_shutdown and good.is_shutdown
    # no spin: one failed read, then an event wait until housekeeping reopened it
    assert broken.calls <= 10, broken.calls
    assert "reading the bus failed (Error receiving: Network is down)" in caplog.text
