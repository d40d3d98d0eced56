"""Helpers for transport-fault tests: a `gyrotherm run` subprocess with a real sd_notify
socket, its CPU time, a TCP peer that accepts and never answers, a subscriber process."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

STOP_BOUND_S = 5.0  # SIGTERM → exit, generous on 2 loaded cores; the unit allows 15 s
WAIT_S = 30.0


class Lines:
    """Collects a pipe's lines on a thread; wait for one matching a pattern (bounded)."""

    def __init__(self, pipe: IO[str]) -> None:
        self.lines: list[str] = []
        self._cond = threading.Condition()
        self.closed = False
        threading.Thread(target=self._pump, args=(pipe,), daemon=True).start()

    def _pump(self, pipe: IO[str]) -> None:
        for line in pipe:
            with self._cond:
                self.lines.append(line)
                self._cond.notify_all()
        with self._cond:
            self.closed = True
            self._cond.notify_all()

    def wait_for(self, pattern: str, timeout_s: float = WAIT_S) -> str | None:
        rx = re.compile(pattern)
        with self._cond:
            self._cond.wait_for(
                lambda: self.closed or any(rx.search(x) for x in self.lines), timeout_s)
            return next((x for x in self.lines if rx.search(x)), None)

    def text(self) -> str:
        with self._cond:
            self._cond.wait_for(lambda: self.closed, WAIT_S)
            return "".join(self.lines)


class NotifyLog:
    """A real sd_notify socket: records (monotonic time, datagram) as the daemon sends."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._sock.bind(str(path))
        self._sock.settimeout(0.2)
        self.messages: list[tuple[float, str]] = []
        self._cond = threading.Condition()
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._pump, daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        while not self._done.is_set():
            try:
                data = self._sock.recv(4096).decode()
            except TimeoutError:
                continue
            with self._cond:
                self.messages.append((time.monotonic(), data))
                self._cond.notify_all()

    def wait_for(self, key: str, timeout_s: float = WAIT_S) -> float | None:
        """Monotonic time of the first datagram with line ``key``, or None."""
        with self._cond:
            self._cond.wait_for(lambda: self.first(key) is not None, timeout_s)
            return self.first(key)

    def wait_after(self, key: str, after: float, timeout_s: float = WAIT_S) -> float | None:
        """Monotonic time of the first datagram with line ``key`` received at or after
        ``after``, or None."""
        def found() -> float | None:
            return next((t for t, m in self.messages if t >= after and key in m.splitlines()),
                        None)

        with self._cond:
            self._cond.wait_for(lambda: found() is not None, timeout_s)
            return found()

    def first(self, key: str) -> float | None:
        return next((t for t, m in self.messages if key in m.splitlines()), None)

    def times(self, key: str, since: float = -1e18, until: float = 1e18) -> list[float]:
        with self._cond:
            return [t for t, m in self.messages if key in m.splitlines() and since <= t <= until]

    def close(self) -> None:
        self._done.set()
        self._thread.join(WAIT_S)
        self._sock.close()


def cpu_s(pid: int) -> float:
    """utime + stime of a process (all threads) from /proc/PID/stat, s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class DaemonProc:
    """``python -m gyrotherm run --config FILE`` with NOTIFY_SOCKET and WATCHDOG_USEC."""

    def __init__(self, config: Path, notify: NotifyLog | None = None, *,
                 watchdog_usec: int = 500_000) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        if notify is not None:
            env.update(NOTIFY_SOCKET=str(notify.path), WATCHDOG_USEC=str(watchdog_usec))
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "gyrotherm", "run", "--config", str(config)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        assert self.proc.stdout is not None and self.proc.stderr is not None
        self.out, self.err = Lines(self.proc.stdout), Lines(self.proc.stderr)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def terminate(self) -> float:
        """SIGTERM; the seconds until the process exited (raises after STOP_BOUND_S × 4)."""
        t0 = time.monotonic()
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(STOP_BOUND_S * 4)
        return time.monotonic() - t0

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def summary(self) -> tuple[int, int, dict[str, int]]:
        """(frames in, published, drops) from the line `gyrotherm run` prints at exit."""
        text = self.out.text()
        m = re.search(r"frames in (\d+), published (\d+), dropped (\d+) (\{.*\})", text)
        assert m, f"no summary line in stdout: {text!r}\nstderr: {self.err.text()}"
        drops = {k: int(v) for k, v in re.findall(r"'(\w+)': (\d+)", m[4])}
        assert sum(drops.values()) == int(m[3])
        return int(m[1]), int(m[2]), drops


class SilentPeer:
    """Accepts TCP connections on 127.0.0.1 and never says a word (no ``< hi >``)."""

    def __init__(self) -> None:
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(8)
        self.port: int = self._listener.getsockname()[1]
        self.accepted: list[socket.socket] = []
        self._cond = threading.Condition()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            with self._cond:
                self.accepted.append(conn)
                self._cond.notify_all()

    def wait_accepted(self, n: int, timeout_s: float = WAIT_S) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: len(self.accepted) >= n, timeout_s)

    def close(self) -> None:
        self._listener.close()
        with self._cond:
            for conn in self.accepted:
                conn.close()


SUBSCRIBER = r"""
import json, sys
from gyrotherm.client import Subscriber
vehicle, sensor, endpoint = sys.argv[1:4]
health = {}
def on_health(h):
    health.update(frames_received=h.frames_received, drops=dict(h.drops))
with Subscriber(vehicle, sensor, connect=[endpoint], on_health=on_health) as sub:
    sub.wait_for(lambda s: s.health.received >= 1, timeout_s=30.0)
    print("READY", flush=True)
    for line in sys.stdin:
        r = sub.stats().rate
        print(json.dumps({"received": r.received, "missing": r.missing, "gaps": r.gaps,
                          "last_seq": r.last_seq, "health": health}), flush=True)
"""


class SubscriberProc:
    """A Subscriber in its own process (so it can be frozen with SIGSTOP)."""

    def __init__(self, vehicle: str, sensor: str, endpoint: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", SUBSCRIBER, vehicle, sensor, endpoint],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        self.out = Lines(self.proc.stdout)

    def stats(self) -> dict[str, object]:
        import json

        assert self.proc.stdin is not None
        n = len(self.out.lines)
        self.proc.stdin.write("stats\n")
        self.proc.stdin.flush()
        with self.out._cond:
            self.out._cond.wait_for(lambda: len(self.out.lines) > n, WAIT_S)
        result: dict[str, object] = json.loads(self.out.lines[n])
        return result

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(WAIT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def write_config(path: Path, *, bus_port: int, zenoh_port: int, extra_can: str = "",
                 extra_zenoh: str = "", zenoh_file: Path | None = None) -> Path:
    zen = (f'config = "{zenoh_file}"\n' if zenoh_file else
           f'listen = ["tcp/127.0.0.1:{zenoh_port}"]\n')
    path.write_text(f"""
vehicle = "faults"
sensor = "imu0"
health_period_s = 0.2
[can]
interface = "socketcand"
host = "127.0.0.1"
port = {bus_port}
channel = "vcan0"
{extra_can}
[zenoh]
{zen}{extra_zenoh}
""")
    return path
