"""A frozen (SIGSTOPped) subscriber process at ≥ 8 k frames/s never costs the watchdog.

The daemon (`gyrotherm run`, real sd_notify socket, pings every 0.25 s) reads a
socketcand stream at ≈ 9 k frames/s and publishes to a subscriber process that is
frozen for 4 s. A put may block at most ``publish_block_max_s`` (0.5 s): the gaps
between watchdog pings stay under WATCHDOG_GAP_MAX_S (2 s, less than half the unit's
WatchdogSec=5s), every frame is accounted for (frames in = published + Σ drops), the
messages given up on are counted (``congestion``, then ``no_subscriber`` once zenoh
closed the link), and after SIGCONT delivery resumes. A second test sends SIGTERM
while the loop is blocked in a put (no ping for 0.8 s) and checks a prompt, clean exit.
"""

from __future__ import annotations

import itertools
import os
import signal
import sys
import threading
import time
from pathlib import Path

import can
import numpy as np

from gyrotherm.codecs import FrameEncoder, RateSample, TemperatureSample
from gyrotherm.sim import SocketcandServer
from gyrotherm.sim._stream import PlayStats, play
from streamkit import free_port

sys.path.insert(0, str(Path(__file__).resolve().parent))
from faultkit import (
    STOP_BOUND_S,
    WAIT_S,
    DaemonProc,
    NotifyLog,
    SubscriberProc,
    write_config,
)

RATE_HZ = 9000.0  # frames per second of sensor time, played at real time
WATCHDOG_GAP_MAX_S = 2.0  # < WatchdogSec/2 = 2.5 s of the unit


def _frames(seconds: float, seed: int = 7) -> list[can.Message]:
    """Rate frames at RATE_HZ with a temperature frame every 100th (≈ 1 %)."""
    rng = np.random.default_rng(seed)
    enc = FrameEncoder()
    n = int(seconds * RATE_HZ)
    noise = rng.normal(0.0, 0.05, size=(n, 3))
    out = []
    for i in range(n):
        t = i / RATE_HZ
        if i % 100 == 0:
            out.append(enc.encode_temperature(TemperatureSample(t, 25.0 + 1e-4 * i)))
        x, y, z = noise[i]
        out.append(enc.encode_rate(RateSample(t, float(x), float(y), float(z))))
    return out


class _Player:
    def __init__(self, frames: list[can.Message], server: SocketcandServer) -> None:
        self.stop = threading.Event()
        self.stats: PlayStats | None = None
        self._thread = threading.Thread(target=self._run, args=(frames, server), daemon=True)
        self._thread.start()

    def _run(self, frames: list[can.Message], server: SocketcandServer) -> None:
        self.stats = play(frames, server, speed=1.0, stop=self.stop)

    def join(self) -> PlayStats:
        self._thread.join(WAIT_S * 4)
        assert self.stats is not None
        return self.stats


def _setup(tmp_path: Path, server: SocketcandServer, notify: NotifyLog, block_s: float
           ) -> tuple[DaemonProc, SubscriberProc]:
    zport = free_port()
    config = write_config(tmp_path / "g.toml", bus_port=server.port, zenoh_port=zport,
                          extra_can="reopen_after_s = 60.0",
                          extra_zenoh=f"publish_block_max_s = {block_s}")
    daemon = DaemonProc(config, notify)
    assert notify.wait_for("READY=1"), daemon.err.lines
    assert server.wait_for_clients(1, WAIT_S)
    sub = SubscriberProc("faults", "imu0", f"tcp/127.0.0.1:{zport}")
    assert sub.out.wait_for("READY"), "subscriber saw no health message"
    return daemon, sub


def test_frozen_subscriber_costs_no_watchdog_and_is_counted(tmp_path: Path) -> None:
    frames = _frames(11.0)
    notify = NotifyLog(tmp_path / "notify.sock")
    pause = threading.Event()  # never set: measured waits, not synchronisation
    try:
        with SocketcandServer(host="127.0.0.1", port=0) as server:
            daemon, sub = _setup(tmp_path, server, notify, 0.5)
            try:
                player = _Player(frames, server)
                assert not pause.wait(2.0)
                os.kill(sub.proc.pid, signal.SIGSTOP)
                t_stop = time.monotonic()
                assert not pause.wait(4.0)
                os.kill(sub.proc.pid, signal.SIGCONT)
                before = sub.stats()
                played = player.join()
                assert server.flush(WAIT_S)
                # delivery resumes: messages sent after SIGCONT arrive
                last_seq = before["last_seq"]
                assert isinstance(last_seq, int)
                for _ in range(40):
                    after = sub.stats()
                    assert isinstance(after["last_seq"], int)
                    if after["last_seq"] > last_seq + 5000:
                        break
                    pause.wait(0.25)
                assert after["last_seq"] > last_seq + 5000, (before, after)
                t_end = time.monotonic()
                received, published, drops = _stop(daemon)
            finally:
                sub.close()
                daemon.kill()
    finally:
        notify.close()
    err = daemon.err.text()
    pings = notify.times("WATCHDOG=1", since=t_stop - 1.0, until=t_end)
    gaps = [b - a for a, b in itertools.pairwise(pings)]
    print(f"\nframes {played.frames_sent} in {played.duration_s:.1f} s "
          f"({played.frames_sent / played.duration_s:.0f}/s); in {received}, published "
          f"{published}, drops {drops}; subscriber {after}; max watchdog gap "
          f"{max(gaps):.2f} s")
    assert played.frames_sent / played.duration_s >= 8000
    assert max(gaps) < WATCHDOG_GAP_MAX_S, (max(gaps), err)
    assert received == played.frames_sent, err
    assert received == published + sum(drops.values())
    assert drops.get("congestion", 0) > 0, (drops, err)
    assert "blocked" in err and "publish_block_max_s" in err
    missing = after["missing"]
    assert isinstance(missing, int)
    # what the daemon counted as not delivered is a part of what the subscriber missed
    # (the rest: messages in flight on the link zenoh closed, counted as published)
    counted = drops.get("congestion", 0) + drops.get("no_subscriber", 0)
    assert 0 < missing and counted <= missing + played.temperature_frames, (counted, missing)


def test_sigterm_while_blocked_on_a_publish(tmp_path: Path) -> None:
    frames = _frames(20.0)
    notify = NotifyLog(tmp_path / "notify.sock")
    try:
        with SocketcandServer(host="127.0.0.1", port=0) as server:
            daemon, sub = _setup(tmp_path, server, notify, 2.0)
            try:
                player = _Player(frames, server)
                os.kill(sub.proc.pid, signal.SIGSTOP)
                # blocked in a put: no watchdog ping for 0.8 s (pings come every ≤ 0.5 s)
                last = notify.wait_after("WATCHDOG=1", time.monotonic())
                assert last is not None
                while (nxt := notify.wait_after("WATCHDOG=1", last + 1e-6, 0.8)) is not None:
                    last = nxt
                    # the daemon's log says why (a link closed, no subscriber, no frames)
                    assert not player.stats, ("played out without the daemon blocking",
                                              daemon.err.text()[-4000:])
                # the put ends within publish_block_max_s (2 s), the session close is
                # waited for at most 2 s (SESSION_CLOSE_WAIT_S)
                received, published, drops = _stop(daemon, STOP_BOUND_S + 3.0)
                player.stop.set()
                player.join()
            finally:
                sub.close()
                daemon.kill()
    finally:
        notify.close()
    assert received == published + sum(drops.values())


def _stop(daemon: DaemonProc, bound_s: float = STOP_BOUND_S
          ) -> tuple[int, int, dict[str, int]]:
    elapsed = daemon.terminate()
    err = daemon.err.text()
    print(f"\nSIGTERM → exit in {elapsed:.2f} s")
    assert elapsed < bound_s, f"SIGTERM took {elapsed:.1f} s\n{err}"
    assert daemon.proc.returncode == 0, err
    return daemon.summary()
