"""``gyrotherm demo``: the whole chain on embedded defaults, no outside services.

1. Simulate the paper's seven heating runs and a 60-min validation run, fit the
   paper model (eq. 12) and print Tables 1 and 2.
2. Play the validation run as CAN frames over the socketcand protocol on
   127.0.0.1 (accelerated), into the daemon (python-can ``socketcand`` client →
   decode → Kalman T/ΔT → compensation → Zenoh on tcp/127.0.0.1), and watch it
   with the client library: a live view, then a closing summary.
"""

from __future__ import annotations

import argparse
import math
import socket
import sys
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the demo's modules (simulator, client, daemon) load when it runs
    from gyrotherm.codecs._wire import RateMessage, StateMessage
    from gyrotherm.daemon import RunSummary


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class _LiveView:
    """Prints one line every ``every_s`` of sensor time; keeps what the summary needs."""

    def __init__(self, every_s: float) -> None:
        self.every_s = every_s
        self._next = -math.inf
        self.state: StateMessage | None = None
        self.raw: list[tuple[float, float, float]] = []
        self.corrected: list[tuple[float, float, float]] = []
        self.seqs: list[int] = []

    def on_state(self, msg: StateMessage) -> None:
        self.state = msg

    def on_rate(self, msg: RateMessage) -> None:
        self.raw.append(msg.raw_rate_dps)
        self.corrected.append(msg.rate_dps)
        self.seqs.append(msg.seq)
        if msg.sensor_time_s >= self._next:
            self._next = msg.sensor_time_s + self.every_s
            s = self.state
            t_c = s.temperature_c if s else math.nan
            d_c = s.delta_t_c if s else math.nan
            print(f"t={msg.sensor_time_s / 60:6.1f} min  T={t_c:6.2f} °C  ΔT={d_c:6.2f} °C  "
                  f"raw x={msg.raw_rate_dps[0]:+.3f}  corrected x={msg.rate_dps[0]:+.3f} °/s  "
                  f"flags={int(msg.flags):#04x}", flush=True)


def _rms(values: Any) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def cmd_demo(args: argparse.Namespace) -> int:
    from gyrotherm.cli._paper import paper_tables

    print("== 1. Fit: the paper's chamber experiment, simulated ==", flush=True)
    valid, cal = paper_tables(args)  # the eq. 12 calibration, streamed below
    print(f"\n== 2. Stream: {valid.name} as CAN frames → daemon → Zenoh → client "
          f"({args.speed:g}× real time) ==", flush=True)
    with tempfile.TemporaryDirectory(prefix="gyrotherm-demo-") as tmp:
        cal_path = cal.save(Path(tmp) / "calibration.json")
        summary, view, stats = _stream(valid, cal_path, speed=args.speed)
    raw = np.array(view.raw)
    cor = np.array(view.corrected)
    rows = np.array(view.seqs)  # one rate frame per row: seq = row of the run
    print("\n== Summary ==  (the gyro is at rest: raw output = bias + noise)")
    if len(raw):
        for j, axis in enumerate("xyz"):
            truth = valid.true_bias_dps[axis][rows]
            applied = raw[:, j] - cor[:, j]
            print(f"axis {axis}: output RMS raw {_rms(raw[:, j]):.4f} °/s → compensated "
                  f"{_rms(cor[:, j]):.4f} °/s; bias error RMS (vs the simulator's true "
                  f"bias) {_rms(truth):.4f} → {_rms(applied - truth):.4f} °/s")
    print(f"frames in {summary.frames_received}, published {summary.frames_published}, "
          f"dropped {sum(summary.drops.values())} by reason {dict(sorted(summary.drops.items()))}")
    print(f"client: {stats.rate.received} rate messages, gaps {stats.rate.gaps}, "
          f"latency p50 {stats.rate.latency.p50_s * 1e3:.2f} ms, "
          f"p99 {stats.rate.latency.p99_s * 1e3:.2f} ms")
    ok = summary.frames_received == summary.frames_published + sum(summary.drops.values())
    return 0 if ok else 1


def _wait_delivered(sub: Any, n_rate: int, *, stall_s: float = 10.0) -> None:
    """Wait until the subscriber has all ``n_rate`` rate messages, as long as they keep
    coming (a loaded machine only slows the chain down); give up after ``stall_s``
    seconds without progress, saying how many are missing."""
    seen = -1
    while sub.stats().rate.received > seen:
        seen = sub.stats().rate.received
        if sub.wait_for(lambda s: s.rate.received >= n_rate, timeout_s=stall_s):
            return
    print(f"warning: {n_rate - seen} of {n_rate} rate messages had not arrived after "
          f"{stall_s:g} s without progress; the summary covers what did", file=sys.stderr)


def _stream(run: Any, cal_path: Path, *, speed: float) -> tuple[RunSummary, _LiveView, Any]:
    from gyrotherm.client import Subscriber
    from gyrotherm.codecs import FrameEncoder
    from gyrotherm.daemon import Daemon, parse_config
    from gyrotherm.sim import SocketcandServer
    from gyrotherm.sim._stream import FlushingSink, frames_from_run, play

    zport = _free_port()
    view = _LiveView(every_s=300.0)
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        cfg = parse_config({
            "vehicle": "demo", "sensor": "imu0", "calibration": str(cal_path),
            "health_period_s": 1.0,
            "can": {"interface": "socketcand", "host": "127.0.0.1", "port": server.port,
                    "channel": "vcan0", "recv_timeout_s": 0.1},
            "zenoh": {"listen": [f"tcp/127.0.0.1:{zport}"]},
        })
        daemon = Daemon(cfg)
        result: dict[str, RunSummary] = {}
        thread = threading.Thread(target=lambda: result.update(s=daemon.run()), daemon=True)
        thread.start()
        if not daemon.ready.wait(30.0) or not server.wait_for_clients(1, 30.0):
            raise RuntimeError("the daemon did not come up within 30 s")
        with Subscriber("demo", "imu0", connect=[f"tcp/127.0.0.1:{zport}"],
                        on_rate=view.on_rate, on_state=view.on_state) as sub:
            sub.wait_for(lambda s: s.health.received >= 1, timeout_s=30.0)
            frames = frames_from_run(run, encoder=FrameEncoder())
            played = play(frames, FlushingSink(server), speed=speed)
            server.flush(30.0)
            _wait_delivered(sub, played.rate_frames)
            daemon.stop()
            thread.join(30.0)
            stats = sub.stats()
    return result["s"], view, stats


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    demo = sub.add_parser("demo", help="the whole chain on embedded defaults (fit, then stream)")
    demo.add_argument("--seed", type=int, default=1, help="random seed")
    demo.add_argument("--rate-hz", type=float, default=10.0, help="sample rate, Hz")
    demo.add_argument("--axis", choices=("x", "y", "z"), default="x", help="axis of Table 1")
    demo.add_argument("--speed", type=float, default=300.0,
                      help="playback speed, × real time (0 = as fast as possible)")
    demo.add_argument("--out", default=None, metavar="DIR",
                      help="also write the simulated runs to this DIRECTORY (created; "
                      "default: not written)")
    demo.set_defaults(func=cmd_demo)
