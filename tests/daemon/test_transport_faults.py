"""Transport faults against a real `gyrotherm run` process with a real sd_notify socket.

* start: the bus is not there yet → the daemon retries with backoff and sends READY=1
  only once the bus (and Zenoh) are up;
* SIGTERM is honoured within STOP_BOUND_S (the unit allows 15 s) while starting (a Zenoh
  client waiting for its router), waiting for the bus, mid-handshake (a peer that
  accepts TCP and never says ``< hi >``) and reopening, always with the summary line;
* a vanished socketcand peer: reopened with backoff, no busy loop (CPU from
  /proc/PID/stat), the watchdog keeps coming, STATUS= says the bus is down.
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from gyrotherm.sim import SocketcandServer
from streamkit import dead_port, free_port

sys.path.insert(0, str(Path(__file__).resolve().parent))
from faultkit import (
    STOP_BOUND_S,
    WAIT_S,
    DaemonProc,
    NotifyLog,
    SilentPeer,
    cpu_s,
    write_config,
)

WATCHDOG_GAP_MAX_S = 2.0  # < WatchdogSec/2 = 2.5 s of the unit


@pytest.fixture()
def notify(tmp_path: Path) -> Iterator[NotifyLog]:
    log = NotifyLog(tmp_path / "notify.sock")
    yield log
    log.close()


def _stop_cleanly(daemon: DaemonProc) -> tuple[int, int, dict[str, int]]:
    try:
        elapsed = daemon.terminate()
    finally:
        daemon.kill()
    err = daemon.err.text()
    print(f"\nSIGTERM → exit in {elapsed:.2f} s")
    assert elapsed < STOP_BOUND_S, f"SIGTERM took {elapsed:.1f} s\n{err}"
    assert daemon.proc.returncode == 0, err
    assert "signal SIGTERM: stopping" in err
    return daemon.summary()


def test_start_waits_for_the_bus_and_is_ready_only_then(tmp_path: Path,
                                                        notify: NotifyLog) -> None:
    bus_port = free_port()
    config = write_config(tmp_path / "g.toml", bus_port=bus_port, zenoh_port=free_port())
    daemon = DaemonProc(config, notify)
    try:
        assert daemon.err.wait_for(r"waiting for the bus: attempt 2 failed"), daemon.err.lines
        assert notify.first("READY=1") is None  # no bus yet: not ready
        assert any("STATUS=waiting for the bus" in m for _, m in notify.messages)
        with SocketcandServer(host="127.0.0.1", port=bus_port) as server:
            opened = notify.wait_for("READY=1")
            assert opened is not None, daemon.err.lines
            assert server.wait_for_clients(1, WAIT_S)
            assert daemon.err.wait_for(r"INFO gyrotherm.daemon: up: ")
            attempts = [x for x in daemon.err.lines if "waiting for the bus: attempt" in x]
            # backoff: 0.1 s doubling to 2 s, one line per attempt, not a flood
            assert 2 <= len(attempts) <= 20, attempts
            received, published, drops = _stop_cleanly(daemon)
    finally:
        daemon.kill()
    assert received == published + sum(drops.values())


def test_start_gives_up_after_start_timeout(tmp_path: Path) -> None:
    with dead_port() as port:
        config = write_config(tmp_path / "g.toml", bus_port=port, zenoh_port=free_port(),
                              extra_can="start_timeout_s = 1.0")
        daemon = DaemonProc(config)
        try:
            daemon.proc.wait(WAIT_S)
        finally:
            daemon.kill()
    err = daemon.err.text()
    assert daemon.proc.returncode == 2, err
    assert "no CAN bus within start_timeout_s = 1 s" in err, err


@pytest.mark.parametrize("state", ["starting", "waiting_for_bus", "mid_handshake",
                                   "reopening"])
def test_sigterm_is_honoured_in_every_state(tmp_path: Path, state: str) -> None:
    zenoh_port = free_port()
    extra_can, zenoh_file = "reopen_after_s = 1.0", None
    peer = SilentPeer()
    server: SocketcandServer | None = None
    try:
        if state == "starting":  # a Zenoh client that waits 60 s for a router nobody runs
            zenoh_file = tmp_path / "client.json5"
            zenoh_file.write_text(json.dumps({
                "mode": "client",
                "connect": {"endpoints": [f"tcp/127.0.0.1:{free_port()}"], "timeout_ms": 60000},
                "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
            }))
            bus_port = peer.port
        elif state == "reopening":
            server = SocketcandServer(host="127.0.0.1", port=0).start()
            bus_port = server.port
        else:
            bus_port = peer.port
        config = write_config(tmp_path / "g.toml", bus_port=bus_port, zenoh_port=zenoh_port,
                              extra_can=extra_can, zenoh_file=zenoh_file)
        if state == "waiting_for_bus":
            peer.close()  # refused from now on
        daemon = DaemonProc(config)
        try:
            if state == "starting":
                assert daemon.err.wait_for(r"starting: zenoh session"), daemon.err.lines
                assert not peer.accepted  # still opening the Zenoh session
            elif state == "waiting_for_bus":
                assert daemon.err.wait_for(r"waiting for the bus: attempt 3 failed")
            elif state == "mid_handshake":
                # the port probe, then python-can's client, which waits for "< hi >"
                assert peer.wait_accepted(2), daemon.err.lines
            else:
                assert server is not None
                assert daemon.err.wait_for(r"gyrotherm.daemon: up: "), daemon.err.lines
                server.shutdown()
                assert daemon.err.wait_for(r"reopening socketcand"), daemon.err.lines
            received, published, drops = _stop_cleanly(daemon)
        finally:
            daemon.kill()
    finally:
        peer.close()
        if server is not None:
            server.shutdown()
    assert (received, published, drops) == (0, 0, {})


def test_vanished_peer_is_reopened_without_spinning(tmp_path: Path,
                                                    notify: NotifyLog) -> None:
    bus_port = free_port()
    config = write_config(tmp_path / "g.toml", bus_port=bus_port, zenoh_port=free_port(),
                          extra_can="reopen_after_s = 1.0")
    daemon = DaemonProc(config, notify)
    try:
        with SocketcandServer(host="127.0.0.1", port=bus_port) as server:
            assert notify.wait_for("READY=1"), daemon.err.lines
            assert server.wait_for_clients(1, WAIT_S)
        # the peer is gone (connection closed, port refused)
        assert daemon.err.wait_for(r"reopening socketcand"), daemon.err.lines
        assert daemon.err.wait_for(r"reopening socketcand .* failed \(attempt 2")
        t0, cpu0 = notify.wait_for("WATCHDOG=1"), cpu_s(daemon.pid)
        assert t0 is not None
        # 3 s of a vanished peer, measured between two watchdog pings
        t1 = notify.wait_after("WATCHDOG=1", t0 + 3.0)
        cpu1 = cpu_s(daemon.pid)
        assert t1 is not None, daemon.err.lines
        pings = notify.times("WATCHDOG=1", since=t0, until=t1)
        cpu_share = (cpu1 - cpu0) / (t1 - t0)
        assert cpu_share < 0.05, f"{cpu_share:.1%} of a core while the peer is gone"
        gaps = [b - a for a, b in itertools.pairwise(pings)]
        assert gaps and max(gaps) < WATCHDOG_GAP_MAX_S, gaps
        status = [m for _, m in notify.messages if "STATUS=" in m][-1]
        assert "bus down" in status, status
        # the peer comes back on the same port: the daemon reconnects
        with SocketcandServer(host="127.0.0.1", port=bus_port) as server:
            assert server.wait_for_clients(1, WAIT_S), daemon.err.lines
            assert daemon.err.wait_for(r"bus socketcand .* reopened after")
            _stop_cleanly(daemon)
    finally:
        daemon.kill()
    print(f"CPU while the peer was gone: {cpu_share:.2%} of a core")
