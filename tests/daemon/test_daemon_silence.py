"""A silent bus: health says so, the bus is reopened, the watchdog stops when the loop is stuck,
and queries see a consistent snapshot."""

from __future__ import annotations

import socket
import threading
import uuid
from dataclasses import replace
from pathlib import Path

import can

from gyrotherm.bus import FrameSource, open_bus
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, Run, StatusFlags
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, Notifier, parse_config
from streamkit import free_port, run_frames

TIMEOUT_S = 20.0


def _cfg(tmp_path: Path, cal: Calibration, port: int, channel: str) -> dict[str, object]:
    cal = replace(cal, estimator=replace(cal.estimator, stale_after_s=0.3))
    return {
        "vehicle": "quiet", "sensor": "imu0",
        "calibration": str(cal.save(tmp_path / "cal.json")),
        "health_period_s": 0.1,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.02,
                "reopen_after_s": 0.5},
        "estimator": {"stale_after_s": 0.3},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
    }


def test_silent_bus_is_flagged_and_reopened(tmp_path: Path, short_runs: list[Run],
                                            stream_calibration: Calibration) -> None:
    port, channel = free_port(), f"q-{uuid.uuid4().hex[:8]}"
    daemon = Daemon(parse_config(_cfg(tmp_path, stream_calibration, port, channel)))
    thread = threading.Thread(target=daemon.run, daemon=True)
    thread.start()
    assert daemon.ready.wait(TIMEOUT_S)
    healths = []
    got_stale = threading.Event()

    def on_health(h):  # type: ignore[no-untyped-def]
        healths.append(h)
        if h.frames_received > 0 and h.flags & StatusFlags.TEMPERATURE_STALE:
            got_stale.set()

    try:
        with Subscriber("quiet", "imu0", connect=[f"tcp/127.0.0.1:{port}"],
                        on_health=on_health) as sub, \
                open_bus(interface="virtual", channel=channel) as bus:
            assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
            # the daemon reopens its silent bus every 0.5 s from the start: frames sent
            # while it reopens are lost (it was silent), so send again until 60 arrived
            for _ in range(5):
                for msg in run_frames(short_runs[0].slice(0, 60), FrameEncoder()):
                    bus.send(msg)
                if sub.wait_for(lambda s: s.rate.received >= 60, timeout_s=3.0):
                    break
            assert sub.stats().rate.received >= 60
            # then silence: health flags it, and the daemon reopens the bus
            assert got_stale.wait(TIMEOUT_S)
            assert _wait(lambda: daemon.bus_reopens >= 1)
            # frames sent after the reopen still arrive
            n = sub.stats().rate.received
            for _ in range(5):
                for msg in run_frames(short_runs[0].slice(60, 80), FrameEncoder()):
                    bus.send(msg)
                if sub.wait_for(lambda s: s.rate.received >= n + 20, timeout_s=3.0):
                    break
            assert sub.stats().rate.received >= n + 20
            info = sub.query_calibration(timeout_s=5.0)
    finally:
        daemon.stop()
        thread.join(TIMEOUT_S)
    assert not thread.is_alive()
    assert info.health is not None
    h = info.health
    assert h.frames_received == h.frames_published + sum(h.drops.values())


class _StuckSource(FrameSource):
    """recv blocks until released: a stuck pipeline."""

    def __init__(self) -> None:
        self.stuck = threading.Event()
        self.release = threading.Event()
        self._down = False

    def recv(self, timeout_s: float | None = None) -> can.Message | None:
        if self.stuck.is_set():
            self.release.wait(TIMEOUT_S)
            self.stuck.clear()
        return None

    @property
    def is_shutdown(self) -> bool:
        return self._down

    def shutdown(self) -> None:
        self._down = True


def test_watchdog_stops_when_the_loop_is_stuck(tmp_path: Path,
                                               stream_calibration: Calibration) -> None:
    path = tmp_path / "notify.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(str(path))
        sock.settimeout(TIMEOUT_S)
        cfg = parse_config(_cfg(tmp_path, stream_calibration, free_port(), "unused"))
        daemon = Daemon(cfg, notifier=Notifier(str(path), watchdog_interval_s=0.2))
        source = _StuckSource()
        thread = threading.Thread(target=daemon.run, kwargs={"source": source}, daemon=True)
        thread.start()
        assert _recv_key(sock, "WATCHDOG=1", TIMEOUT_S)
        source.stuck.set()
        _drain(sock, 0.3)  # anything already in flight
        # stuck: no WATCHDOG=1 for many intervals (systemd would restart us)
        assert not _recv_key(sock, "WATCHDOG=1", 1.0)
        source.release.set()
        assert _recv_key(sock, "WATCHDOG=1", TIMEOUT_S)  # unstuck: petting resumes
        daemon.stop()
        thread.join(TIMEOUT_S)
    assert not thread.is_alive()


def _recv_key(sock: socket.socket, key: str, timeout_s: float) -> bool:
    sock.settimeout(timeout_s)
    try:
        while True:
            if key in sock.recv(4096).decode().splitlines():
                return True
    except TimeoutError:
        return False


def _drain(sock: socket.socket, timeout_s: float) -> None:
    sock.settimeout(timeout_s)
    try:
        while True:
            sock.recv(4096)
    except TimeoutError:
        return


def _wait(predicate, timeout_s: float = TIMEOUT_S) -> bool:  # type: ignore[no-untyped-def]
    done = threading.Event()
    for _ in range(int(timeout_s / 0.05)):
        if predicate():
            return True
        done.wait(0.05)
    return bool(predicate())
