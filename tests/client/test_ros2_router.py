"""``gyrotherm record --ros2`` reaching a ROS 2 node *behind a router*, as ROS 2 users run
it: the node's Zenoh session has rmw_zenoh's default settings and only knows the router.

The peer and router settings are rmw_zenoh's own defaults, read from its sources
(ros2/rmw_zenoh ``rmw_zenoh_cpp/config/DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5`` at commit
076f2e715b54132d00a605e1c45e13401d5e7342 and ``DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5`` at
commit bfc065f8c80cc3bc4d1963dc44ac5a472460903a): the node is a peer that connects to the
router, listens on ``tcp/localhost:0``, has multicast scouting off and gossip on
(multihop off, target the router, autoconnect to routers and peers, strategy
``greater-zid`` between peers); the router (``rmw_zenohd``) has gossip on and
``peers_failover_brokering`` on. Only the addresses differ: 127.0.0.1 and ephemeral
ports, never 7447 (the machine's other tests) and never all interfaces. The router runs
as eclipse-zenoh in router mode and, when installed, as a ``zenohd`` process (rmw_zenohd
is zenohd with that configuration).

Two topologies (README, "ROS 2 live, over Zenoh"):

* ``shared router``: one router for the daemon and the ROS 2 nodes; the daemon is a
  client of it (deploy/zenoh/client-of-router.json5, its port changed), record connects
  to the router only: the README's command verbatim but for the port;
* ``separate``: the daemon a peer on its own port (the bench default), a router for the
  ROS 2 side; record connects to both.

The node counts the Imu samples and the liveliness tokens (rmw_zenoh's graph) and sees
the tokens removed when record stops.
"""

from __future__ import annotations

import json
import queue
import re
import shlex
import shutil
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from gyrotherm.bus import open_bus
from gyrotherm.client._record import record_main
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, parse_config
from streamkit import free_port, run_frames, stop_process

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "daemon"))
from faultkit import Lines

TIMEOUT_S = 20.0
ROOT = Path(__file__).resolve().parents[2]


ROUTER: dict[str, Any] = {
    "mode": "router",
    "connect": {"endpoints": []},
    "scouting": {"multicast": {"enabled": False},
                 "gossip": {"enabled": True, "multihop": False}},
    "timestamping": {"enabled": {"router": True, "peer": True, "client": True}},
    "routing": {"router": {"peers_failover_brokering": True},
                "peer": {"mode": "peer_to_peer"}},
}
"""rmw_zenohd's DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5 (its listen endpoint aside)."""


def router_config(port: int) -> zenoh.Config:
    """rmw_zenohd's DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5, on 127.0.0.1:``port``."""
    return zenoh.Config.from_json5(json.dumps(
        {**ROUTER, "listen": {"endpoints": [f"tcp/127.0.0.1:{port}"]}}))


def node_config(router_port: int) -> zenoh.Config:
    """A ROS 2 node's session: DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5, the router on
    127.0.0.1:``router_port`` instead of localhost:7447."""
    return zenoh.Config.from_json5(json.dumps({
        "mode": "peer",
        "connect": {"endpoints": [f"tcp/127.0.0.1:{router_port}"]},
        "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
        "scouting": {
            "multicast": {"enabled": False},
            "gossip": {"enabled": True, "multihop": False,
                       "target": {"router": ["router", "peer"], "peer": ["router"]},
                       "autoconnect": {"router": [], "peer": ["router", "peer"]},
                       "autoconnect_strategy": {"peer": {"to_router": "always",
                                                         "to_peer": "greater-zid"}}},
        },
        "timestamping": {"enabled": {"router": True, "peer": True, "client": True}},
        "routing": {"router": {"peers_failover_brokering": True},
                    "peer": {"mode": "peer_to_peer"}},
    }))


class Node:
    """What a ROS 2 subscriber under rmw_zenoh sees: samples on the domain's keys and the
    liveliness tokens of the graph."""

    def __init__(self, router_port: int) -> None:
        self.session = zenoh.open(node_config(router_port))
        self.samples: queue.Queue[str] = queue.Queue()
        self.tokens: queue.Queue[tuple[Any, str]] = queue.Queue()
        self._subs = [
            self.session.declare_subscriber("0/gyrotherm/imu0/imu/**",
                                            lambda s: self.samples.put(str(s.key_expr))),
            self.session.liveliness().declare_subscriber(
                "@ros2_lv/0/**", lambda s: self.tokens.put((s.kind, str(s.key_expr))),
                history=True),
        ]

    def token_events(self, kind: Any, n: int) -> list[str]:
        out: list[str] = []
        deadline = time.monotonic() + TIMEOUT_S
        while len(out) < n:
            try:
                k, key = self.tokens.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            if k == kind:
                out.append(key)
        return out

    def count_samples(self, n: int) -> int:
        got = 0
        deadline = time.monotonic() + TIMEOUT_S
        while got < n:
            try:
                self.samples.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            got += 1
        return got

    def close(self) -> None:
        self.session.close()


def _daemon(tmp_path: Path, calibration: Calibration, zenoh_table: dict[str, Any]
            ) -> tuple[Daemon, threading.Thread, str]:
    channel = f"r2-{uuid.uuid4().hex[:8]}"
    cfg = parse_config({
        "vehicle": "veh01", "sensor": "imu0",
        "calibration": str(calibration.save(tmp_path / "cal.json")), "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": zenoh_table}, base_dir=tmp_path)
    d = Daemon(cfg)
    thread = threading.Thread(target=d.run, daemon=True)
    thread.start()
    assert d.ready.wait(TIMEOUT_S)
    return d, thread, channel


def _client_of_router(tmp_path: Path, router_port: int) -> Path:
    """deploy/zenoh/client-of-router.json5 with the router's port and no login (the
    ACL router's login is proved in tests/deploy)."""
    text = (ROOT / "deploy" / "zenoh" / "client-of-router.json5").read_text()
    assert "tcp/127.0.0.1:7447" in text and 'user: "gyrotherm-daemon",' in text
    out = tmp_path / "client.json5"
    out.write_text(text.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{router_port}")
                   .replace('user: "gyrotherm-daemon",', "")
                   .replace('password: "REPLACE-WITH-A-SECRET",', ""))
    return out


def readme_record_argv() -> list[str]:
    """The README's ``gyrotherm record … --ros2`` line, as a user pastes it."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = next(b for b in re.findall(r"```sh\n(.*?)```", text, re.S) if "--ros2" in b)
    line = next(ln for ln in block.replace("\\\n", " ").splitlines()
                if ln.startswith("gyrotherm record"))
    return shlex.split(line.split("#")[0])[2:]


@pytest.fixture(params=["eclipse-zenoh", "zenohd"])
def router(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[int]:
    """The router on a free loopback port: eclipse-zenoh in router mode in this process,
    or a ``zenohd`` process (rmw_zenohd is zenohd with rmw_zenoh's config) when on PATH."""
    port = free_port()
    if request.param == "eclipse-zenoh":
        session = zenoh.open(router_config(port))
        yield port
        session.close()
        return
    zenohd = shutil.which("zenohd")
    if zenohd is None:
        pytest.skip("zenohd is not on PATH: the eclipse-zenoh variant runs the same router "
                    "engine (install zenohd to run this one too)")
    config = tmp_path / "rmw_zenohd.json5"
    config.write_text(json.dumps({**ROUTER, "listen": {"endpoints": [f"tcp/127.0.0.1:{port}"]}}))
    proc = subprocess.Popen([zenohd, "-c", str(config)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True,
                            env={"RUST_LOG": "info", "PATH": "/usr/bin:/bin"})
    try:
        assert proc.stdout is not None
        lines = Lines(proc.stdout)  # at RUST_LOG=info zenohd logs its bound locators
        assert lines.wait_for(re.escape(f"127.0.0.1:{port}"), TIMEOUT_S), lines.lines
        yield port
    finally:
        stop_process(proc)


@pytest.mark.parametrize("topology", ["shared_router", "separate"])
def test_a_ros2_node_behind_a_router_gets_every_sample_and_the_graph(
        tmp_path: Path, runs: list[Run], calibration: Calibration, router: int,
        topology: str) -> None:
    if topology == "shared_router":
        d, thread, channel = _daemon(tmp_path, calibration,
                                     {"config": str(_client_of_router(tmp_path, router))})
        argv = [a.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{router}")
                for a in readme_record_argv()]
        assert argv.count(f"tcp/127.0.0.1:{router}") == 1  # only the port differs
    else:
        port = free_port()
        d, thread, channel = _daemon(tmp_path, calibration,
                                     {"listen": [f"tcp/127.0.0.1:{port}"]})
        argv = ["--vehicle", "veh01", "--sensor", "imu0", "--connect", f"tcp/127.0.0.1:{port}",
                "--connect", f"tcp/127.0.0.1:{router}", "--ros2"]
    node = Node(router)
    run = runs[1].slice(0, 100)
    try:
        ready, result = threading.Event(), {}
        argv += ["--count", str(len(run)), "-q"]
        rec = threading.Thread(target=lambda: result.update(
            code=record_main(argv, on_ready=lambda _p: ready.set())))
        rec.start()
        assert ready.wait(TIMEOUT_S)
        declared = node.token_events(zenoh.SampleKind.PUT, 8)
        assert len(declared) == 8, declared  # the node and its seven publishers
        with open_bus(interface="virtual", channel=channel) as bus:
            for msg in run_frames(run, FrameEncoder()):
                bus.send(msg)
        received = node.count_samples(len(run))
        rec.join(TIMEOUT_S)
        assert not rec.is_alive() and result["code"] == 0
        assert received == len(run)
        gone = node.token_events(zenoh.SampleKind.DELETE, 8)
        assert sorted(gone) == sorted(declared)
    finally:
        node.close()
        d.stop()
        thread.join(TIMEOUT_S)
