"""A real `gyrotherm run` with [learn] killed with SIGKILL in the middle of a warm-up and
restarted on the same state dir while the gyro keeps running (issue 21 item 4).

The state dir starts with a learnt calibration adopted (three power-ons, learnkit). The
first daemon takes a simulated power-on (stamps: the gyro's time since power-on, from 0)
and is killed KILL_S of sensor time into it — the frames go as fast as the daemon takes
them, so its 60-s periodic save never came after the one at the power-on: the state on
disk is KILL_S stale. The second daemon gets the rest of the same warm-up, from a minute
later on the gyro's clock: left out as ``restart`` (state message and state file),
``power_ons`` unchanged, no warm-up added, nothing adopted, the learnt file byte-identical.
Then a clean power-on in the same daemon (both streams silent for longer than
``power_on_gap_s``, the wall clock seeing it) is learnt.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
from pathlib import Path

from gyrotherm.client import Subscriber
from gyrotherm.codecs._wire import StateMessage
from gyrotherm.compensation import ZeroConfig
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.sim import SocketcandServer
from gyrotherm.sim._life import LIFE_GYRO, power_on
from learnkit import frames, life_of
from streamkit import free_port

sys.path.insert(0, str(Path(__file__).resolve().parent))
from faultkit import Lines

TIMEOUT_S = 60.0
KILL_S = 300.0
BACK_S = KILL_S + 60.0
GAP_S = 1.0
SILENCE_S = 1.5
LEARNT = "car.imu0.learnt-calibration.json"
STATE = "car.imu0.learn-state.json"
LEARN = LearnConfig(min_warmups=3, min_rest_s=60.0, warmup_window_s=900.0)


def _config(path: Path, state_dir: Path, bus_port: int, zport: int) -> Path:
    path.write_text(f"""
vehicle = "car"
sensor = "imu0"
state_dir = "{state_dir}"
health_period_s = 0.2
power_on_gap_s = {GAP_S}
[estimator]
tau_s = {LIFE_GYRO.tau_s}
[zero]
window_s = 30.0
settle_s = 30.0
[learn]
min_warmups = {LEARN.min_warmups}
min_rest_s = {LEARN.min_rest_s}
warmup_window_s = {LEARN.warmup_window_s}
[can]
interface = "socketcand"
host = "127.0.0.1"
port = {bus_port}
channel = "vcan0"
[zenoh]
listen = ["tcp/127.0.0.1:{zport}"]
""")
    return path


class _Daemon:
    def __init__(self, config: Path, server: SocketcandServer, zport: int) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "gyrotherm", "run", "--config",
                                      str(config)], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        assert self.proc.stderr is not None and self.proc.stdout is not None
        self.err, self.out = Lines(self.proc.stderr), Lines(self.proc.stdout)
        assert self.err.wait_for(r"INFO gyrotherm.daemon: up:", TIMEOUT_S), self.err.lines
        assert server.wait_for_clients(1, TIMEOUT_S)
        self.states: list[StateMessage] = []
        self.sub = Subscriber("car", "imu0", connect=[f"tcp/127.0.0.1:{zport}"],
                              on_state=self.states.append)
        assert self.sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)

    def send(self, server: SocketcandServer, msgs: list) -> StateMessage:
        """Send ``msgs``; wait for the state message of the last temperature frame."""
        for m in msgs:
            server.send(m)
        assert server.flush(TIMEOUT_S)
        last = max(m.timestamp for m in msgs)
        assert self.sub.wait_for(lambda s: bool(self.states)
                                 and self.states[-1].sensor_time_s >= last - 0.2,
                                 timeout_s=TIMEOUT_S), (self.states[-1:], self.err.lines)
        return self.states[-1]

    def close(self) -> None:
        self.sub.close()
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(TIMEOUT_S)


def test_sigkill_mid_warm_up_and_restart_while_the_gyro_runs(tmp_path: Path) -> None:
    state = tmp_path / "state"
    state.mkdir()
    zero = ZeroConfig(window_s=30.0, settle_s=30.0)
    life_of(state, [power_on(a, warmup_s=300.0, motion_s=20.0, seed=600 + k, name=f"p{k}")
                    for k, a in enumerate((-8.0, 14.0, 38.0))], config=LEARN, zero=zero)
    assert (state / LEARNT).is_file()
    learnt = (state / LEARNT).read_bytes()
    before = json.loads((state / STATE).read_text())
    assert before["power_ons"] == 3 and len(before["learn"]["warmups"]) == 3

    run = power_on(20.0, warmup_s=600.0, seed=650, name="killed")
    msgs = frames(run)
    zport = free_port()
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        config = _config(tmp_path / "g.toml", state, server.port, zport)
        # --- the first daemon: a power-on, killed KILL_S into its warm-up
        d1 = _Daemon(config, server, zport)
        try:
            last = d1.send(server, [m for m in msgs if m.timestamp < KILL_S])
            assert last.learn is not None and last.learn.collecting
            assert last.learn.warmups_used == 3 and last.learn.rejected == {}
            d1.proc.send_signal(signal.SIGKILL)
            assert d1.proc.wait(TIMEOUT_S) == -signal.SIGKILL
        finally:
            d1.close()
        assert server.wait_until_disconnected(TIMEOUT_S)
        killed = (state / STATE).read_bytes()
        at_kill = json.loads(killed)  # whole, valid JSON: the write is atomic
        assert at_kill["power_ons"] == 4 and at_kill["learn"] == before["learn"]
        assert at_kill["power_on_time_s"] == run.time_s[0] == 0.0  # the power-on is saved
        assert at_kill["last_time_s"] < KILL_S - 60.0  # no save came after it: stale
        assert (state / LEARNT).read_bytes() == learnt

        # --- the second daemon, a minute later on the gyro's clock, same warm-up
        d2 = _Daemon(config, server, zport)
        try:
            last = d2.send(server, [m for m in msgs if m.timestamp >= BACK_S])
            assert last.learn is not None and not last.learn.collecting
            assert last.learn.rejected == {"restart": 1} and last.learn.warmups_used == 3
            assert "last power-on left out: restart (1 so far)" in last.learn.status
            assert last.learn.status.startswith("adopted at ")
            assert all(s.learn is not None and not s.learn.collecting
                       and s.learn.rejected == {"restart": 1} for s in d2.states)
            after_restart = json.loads((state / STATE).read_text())  # saved at once
            assert after_restart["power_ons"] == 4 and after_restart["rejected"] == {
                "restart": 1}
            assert after_restart["learn"] == before["learn"]
            assert (state / LEARNT).read_bytes() == learnt  # nothing adopted

            # --- a clean power-on in the same daemon: both streams silent for SILENCE_S
            # (> power_on_gap_s) that the wall clock sees too, then a new warm-up
            threading.Event().wait(SILENCE_S)  # the power-off itself, not a synchronisation
            clean = power_on(5.0, warmup_s=200.0, seed=651, name="clean")
            t0 = float(run.time_s[-1]) + SILENCE_S
            last = d2.send(server, frames(clean, shift_s=t0))
            assert last.learn is not None and last.learn.collecting
            d2.proc.send_signal(signal.SIGTERM)
            assert d2.proc.wait(TIMEOUT_S) == 0, d2.err.text()
        finally:
            d2.close()
    final = json.loads((state / STATE).read_text())
    assert final["power_ons"] == 5 and final["rejected"] == {"restart": 1}
    assert len(final["learn"]["warmups"]) == 4  # the clean power-on, closed at the stop
    assert final["learn"]["warmups"][:3] == before["learn"]["warmups"]
    assert (state / LEARNT).read_bytes() == learnt
    assert "learning: the gyro kept running across the restart" in d2.err.text()
