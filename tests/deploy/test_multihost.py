"""Three hosts, one Zenoh router in the middle, and a router crash mid-stream.

Hosts are Linux network namespaces made by the test (tests/netnskit.py), joined
by veth pairs on test-only /30s that exist only inside them::

    veh 10.231.1.2 ── 10.231.1.1 rtr 10.231.2.1 ── 10.231.2.2 gnd

* veh (vehicle): ``gyrotherm sim stream`` serves a simulated chamber run as
  socketcand on the vehicle's own 127.0.0.1, paced at ≈300 frames/s, into
  ``gyrotherm run`` configured as a Zenoh client of the router with
  deploy/zenoh/client-of-router.json5 (only the router's address changed);
* rtr (router): a router from deploy/zenoh/router.json5 (listening on its two
  link addresses) — ``zenohd -c`` when zenohd is installed, else eclipse-zenoh
  in router mode, the same engine (``python -m netnskit router``);
* gnd (ground): ``python -m netnskit ground``, a ``gyrotherm.client.Subscriber``
  on a client session to the router, printing JSON events.

Variant ``mtls-acl``: the same over mutual TLS only, through the access-control
router of deploy/zenoh/acl-router.json5, with tls-mutual.json5 as the clients'
base (in client mode); certificates are made here with the openssl CLI: a CA,
the router's (SAN = its two link addresses, checked by the clients), the
daemon's (CN gyrotherm-daemon, the only subject allowed to publish) and the
ground station's (CN gyrotherm-viewer, subscribe and query only).

Truth checked, all of it observed on the ground host:

1. corrected rates cross the hosts: rate messages with a nonzero bias and
   ``rate == raw − bias``, and state messages whose bias is the calibration's,
   hand-computed: the calibration is the paper model with only the constant
   and T terms, ``bias = a5 + a2·(T − 25 °C)/10 °C`` per axis;
2. the router is SIGKILLed mid-stream and started again on the same addresses
   and port: rate messages resume without restarting the daemon (same pid,
   health ``uptime_s`` keeps growing, no sequence reset: ``seq`` continues
   past the gap), and the subscriber sees the outage as a gap in ``seq``;
3. the gap is reported in health: ``drops["no_subscriber"]`` grows by about
   the number of messages the subscriber missed (a few may be lost in flight
   when the link dies, before zenoh notices, and are not seen by the daemon)
   (the daemon counts messages that no subscriber matched);
4. the calibration queryable answers across the router; on SIGTERM the daemon
   accounts for every frame: published + dropped = received.

Skips (never fails) without root / CAP_SYS_ADMIN / ``ip``; the zenohd variant
skips when zenohd is not on PATH.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import zenoh

from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.compensation import Calibration, Scaling, ValidRange, get_model
from gyrotherm.estimators import EstimatorConfig
from netnskit import Network, Process, netns_unavailable, remove_stale_namespaces

ROOT = Path(__file__).resolve().parents[2]
DEPLOY_ZENOH = ROOT / "deploy" / "zenoh"
VEHICLE, SENSOR = "mh01", "imu0"
VEH_ADDR, RTR_VEH_ADDR = "10.231.1.2", "10.231.1.1"
RTR_GND_ADDR, GND_ADDR = "10.231.2.1", "10.231.2.2"
ZENOH_PORT = 7447
START_S = 30.0  # a process coming up (imports, zenoh session)
WAIT_S = 20.0  # an event in a running system (reconnection backs off up to 4 s)

# Calibration: paper model terms (T², T, ΔT, T·ΔT, 1) in x = (T − 25)/10, g = ΔT/1.
T_REF_C, T_SCALE_C = 25.0, 10.0
A2 = {"x": 0.08, "y": -0.05, "z": 0.03}  # °/s per 10 °C
A5 = {"x": 0.20, "y": -0.10, "z": 0.15}  # °/s at 25 °C
T_RANGE_C = (-40.0, 125.0)

#: Player: 10 Hz rate + 10 Hz temperature frames at 15× real time ≈ 300 frames/s;
#: 720 s of sensor time ≈ 48 s of wall time, far more than the test needs (it stops it).
PLAYER_ARGS = ["--chamber", "10", "--hold-s", "60", "--rate-hz", "10", "--speed", "15",
               "--seed", "3", "--interface", "socketcand-server", "--host", "127.0.0.1",
               "--port", "0", "--channel", "vcan0", "--wait-clients", "1",
               "--wait-timeout-s", "60"]
MIN_RATES = 150  # rate messages seen before the crash, and again after recovery


def _calibration() -> Calibration:
    return Calibration(
        model=get_model("paper"),
        scaling=Scaling(t_ref_c=T_REF_C, t_scale_c=T_SCALE_C, dt_scale_c=1.0),
        coefficients={a: (0.0, A2[a], 0.0, 0.0, A5[a]) for a in "xyz"},
        valid_range=ValidRange(T_RANGE_C[0], T_RANGE_C[1], -50.0, 50.0),
        estimator=EstimatorConfig(),
    )


def _expected_bias_dps(temperature_c: float) -> list[float]:
    t = min(max(temperature_c, T_RANGE_C[0]), T_RANGE_C[1])
    return [A5[a] + A2[a] * (t - T_REF_C) / T_SCALE_C for a in "xyz"]


def _rewrite(src: Path, dst: Path, old: str, new: str) -> Path:
    """Copy a shipped JSON5 file with exactly one occurrence of ``old`` replaced."""
    text = src.read_text(encoding="utf-8")
    assert text.count(old) == 1, f"{src.name}: expected {old!r} exactly once"
    dst.write_text(text.replace(old, new), encoding="utf-8")
    return dst


@dataclass(frozen=True)
class ZenohFiles:
    """The three hosts' Zenoh configuration files."""

    router: Path
    vehicle: Path
    ground: Path


def _tcp_files(tmp: Path) -> ZenohFiles:
    """The shipped router.json5 and client-of-router.json5: addresses, the router's
    user dictionary and the clients' logins changed (daemon / viewer)."""
    client = DEPLOY_ZENOH / "client-of-router.json5"
    local = '"tcp/127.0.0.1:7447"'
    users = tmp / "gyrotherm-users.txt"
    users.write_text("gyrotherm-daemon:test-daemon-pw\ngyrotherm-viewer:test-viewer-pw\n")
    router = _rewrite(DEPLOY_ZENOH / "router.json5", tmp / "router.json5", f"{local},",
                      f'"tcp/{RTR_VEH_ADDR}:{ZENOH_PORT}", "tcp/{RTR_GND_ADDR}:{ZENOH_PORT}",')
    _rewrite(router, router, '"/etc/zenoh/gyrotherm-users.txt"', json.dumps(str(users)))
    vehicle = _rewrite(client, tmp / "zenoh-vehicle.json5", local,
                       f'"tcp/{RTR_VEH_ADDR}:{ZENOH_PORT}"')
    _rewrite(vehicle, vehicle, '"REPLACE-WITH-A-SECRET"', '"test-daemon-pw"')
    ground = _rewrite(client, tmp / "zenoh-ground.json5", local,
                      f'"tcp/{RTR_GND_ADDR}:{ZENOH_PORT}"')
    _rewrite(ground, ground, '"REPLACE-WITH-A-SECRET"', '"test-viewer-pw"')
    _rewrite(ground, ground, 'user: "gyrotherm-daemon"', 'user: "gyrotherm-viewer"')
    return ZenohFiles(router=router, vehicle=vehicle, ground=ground)


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def _make_pki(pki: Path) -> None:
    """CA and EC P-256 leaves (docs/operations.md recipe), valid for two days."""
    _openssl("req", "-x509", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
             "-nodes", "-keyout", "ca-key.pem", "-out", "ca.pem", "-days", "2",
             "-subj", "/CN=gyrotherm-test-ca", "-set_serial", "1",
             "-addext", "basicConstraints=critical,CA:TRUE",
             "-addext", "keyUsage=critical,keyCertSign,cRLSign", cwd=pki)
    leaves = {"gyrotherm-router": f"IP:{RTR_VEH_ADDR},IP:{RTR_GND_ADDR}",
              "gyrotherm-daemon": f"IP:{VEH_ADDR}", "gyrotherm-viewer": f"IP:{GND_ADDR}"}
    for serial, (name, san) in enumerate(leaves.items(), start=2):
        (pki / f"{name}.ext").write_text(
            "basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature\n"
            f"extendedKeyUsage=serverAuth,clientAuth\nsubjectAltName={san}\n")
        _openssl("req", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
                 "-nodes", "-keyout", f"{name}-key.pem", "-out", f"{name}.csr",
                 "-subj", f"/CN={name}", cwd=pki)
        _openssl("x509", "-req", "-in", f"{name}.csr", "-CA", "ca.pem", "-CAkey", "ca-key.pem",
                 "-set_serial", str(serial), "-days", "2", "-extfile", f"{name}.ext",
                 "-out", f"{name}.pem", cwd=pki)


def _set(config: zenoh.Config, key: str, value: object) -> None:
    config.insert_json5(key, json.dumps(value))


def _write(config: zenoh.Config, path: Path) -> Path:
    path.write_text(str(config), encoding="utf-8")  # zenoh's own JSON of the config
    return path


def _tls_files(tmp: Path) -> ZenohFiles:
    """acl-router.json5 and tls-mutual.json5 (as clients) with this test's certificates."""
    if shutil.which("openssl") is None:
        pytest.skip("the openssl CLI is not installed: cannot make test certificates")
    pki = tmp / "pki"
    pki.mkdir()
    _make_pki(pki)

    def tls(config: zenoh.Config, name: str, directions: tuple[str, ...]) -> None:
        _set(config, "transport/link/tls/root_ca_certificate", str(pki / "ca.pem"))
        for d in directions:
            _set(config, f"transport/link/tls/{d}_certificate", str(pki / f"{name}.pem"))
            _set(config, f"transport/link/tls/{d}_private_key", str(pki / f"{name}-key.pem"))

    router = zenoh.Config.from_file(str(DEPLOY_ZENOH / "acl-router.json5"))
    _set(router, "listen/endpoints", [f"tls/{RTR_VEH_ADDR}:{ZENOH_PORT}",
                                      f"tls/{RTR_GND_ADDR}:{ZENOH_PORT}"])
    tls(router, "gyrotherm-router", ("listen",))

    def client(name: str, router_addr: str, file: str) -> Path:
        config = zenoh.Config.from_file(str(DEPLOY_ZENOH / "tls-mutual.json5"))
        _set(config, "mode", "client")
        _set(config, "listen/endpoints", [])
        _set(config, "connect/endpoints", [f"tls/{router_addr}:{ZENOH_PORT}"])
        tls(config, name, ("listen", "connect"))
        return _write(config, tmp / file)

    return ZenohFiles(router=_write(router, tmp / "router.json5"),
                      vehicle=client("gyrotherm-daemon", RTR_VEH_ADDR, "zenoh-vehicle.json5"),
                      ground=client("gyrotherm-viewer", RTR_GND_ADDR, "zenoh-ground.json5"))


@pytest.fixture()
def network() -> Any:
    reason = netns_unavailable()
    if reason is not None:
        pytest.skip(f"multi-host test needs network namespaces: {reason}")
    remove_stale_namespaces()
    with Network() as net:
        yield net


def _start_router(net: Network, kind: str, config: Path, n: int) -> Process:
    rtr = net.hosts["rtr"]
    if kind == "zenohd":
        zenohd = shutil.which("zenohd")
        assert zenohd is not None
        proc = net.spawn(rtr, [zenohd, "-c", str(config)], name=f"zenohd#{n}",
                         env={"RUST_LOG": "info"})
        # at RUST_LOG=info zenohd logs the locators it listens on once they are bound
        proc.wait_line(re.escape(f"{RTR_GND_ADDR}:{ZENOH_PORT}"), timeout_s=START_S,
                       stream="any")
        return proc
    proc = net.spawn(rtr, [sys.executable, "-m", "netnskit", "router", str(config)],
                     name=f"router#{n}")
    proc.wait_event(lambda e: e.get("event") == "ready", timeout_s=START_S,
                    what="router ready")
    return proc


@pytest.mark.slow
@pytest.mark.parametrize("transport", ["tcp", "mtls-acl"])
@pytest.mark.parametrize("router_kind", ["eclipse-zenoh", "zenohd"])
def test_router_restart_mid_stream_across_three_hosts(
    network: Network, tmp_path: Path, router_kind: str, transport: str
) -> None:
    if router_kind == "zenohd" and shutil.which("zenohd") is None:
        pytest.skip("zenohd is not on PATH; the eclipse-zenoh variant runs the same router "
                    "engine (install zenohd to run this one too)")
    files = _tcp_files(tmp_path) if transport == "tcp" else _tls_files(tmp_path)
    net = network
    veh, rtr, gnd = net.host("veh"), net.host("rtr"), net.host("gnd")
    net.link(veh, VEH_ADDR, rtr, RTR_VEH_ADDR)
    net.link(rtr, RTR_GND_ADDR, gnd, GND_ADDR)
    router_conf = files.router
    router = _start_router(net, router_kind, router_conf, 1)

    # --- vehicle: simulated gyro over socketcand on its loopback, daemon as a client
    player = net.spawn(veh, [sys.executable, "-m", "gyrotherm", "sim", "stream", *PLAYER_ARGS],
                       name="player")
    port = int(player.wait_line(r"listening on 127\.0\.0\.1:(\d+)", timeout_s=START_S)[1])
    cal = _calibration().save(tmp_path / "imu0.calibration.json")
    (tmp_path / "gyrotherm.toml").write_text(f"""
vehicle = "{VEHICLE}"
sensor = "{SENSOR}"
calibration = "{cal.name}"
health_period_s = 0.2

[can]
interface = "socketcand"
host = "127.0.0.1"
port = {port}
channel = "vcan0"
recv_timeout_s = 0.05

[zenoh]
config = "{files.vehicle.name}"
""", encoding="utf-8")
    daemon = net.spawn(veh, [sys.executable, "-m", "gyrotherm", "run", "--config",
                             str(tmp_path / "gyrotherm.toml")], name="daemon")
    daemon.wait_line(r"INFO gyrotherm\.daemon: up:", timeout_s=START_S, stream="err")
    daemon_pid = daemon.pid

    # --- ground: subscriber as a client of the router, on the other link
    ground = net.spawn(gnd, [sys.executable, "-m", "netnskit", "ground", "--vehicle", VEHICLE,
                             "--sensor", SENSOR, "--zenoh-config", str(files.ground)],
                       name="ground", stdin=True)

    # 1. corrected rates cross the hosts
    def calibrated(e: dict[str, Any]) -> bool:
        return bool(e["event"] == "health" and e["checks"]["bias_nonzero"] >= MIN_RATES
                    and e["last_state"] and e["last_state"]["temperature_c"] is not None)

    i_before, before = ground.wait_event(calibrated, timeout_s=START_S,
                                         what=f"{MIN_RATES} rate messages with a bias")
    checks = before["checks"]
    assert checks["calibrated"] == checks["rates"], before  # NO_CALIBRATION never set
    assert checks["max_residual_dps"] < 1e-9, before  # rate == raw − bias
    state = before["last_state"]
    assert not state["flags"] & StatusFlags.NO_CALIBRATION, state
    assert state["bias_dps"] == pytest.approx(_expected_bias_dps(state["temperature_c"]),
                                              abs=1e-12)
    assert before["streams"]["rate"]["resets"] == 0, before
    # the calibration id names the file: the first 16 hex digits of its sha256
    cal_id = hashlib.sha256(cal.read_bytes()).hexdigest()[:16]
    assert before["health"]["calibration_id"] == cal_id, before
    seq_before = before["streams"]["rate"]["last_seq"]
    missing_before = before["streams"]["rate"]["missing"] + before["streams"]["state"]["missing"]
    no_sub_before = before["health"]["drops"].get("no_subscriber", 0)

    # 2. crash the router mid-stream and start it again on the same addresses and port
    router.stop(sig=signal.SIGKILL)
    ground.wait_event(lambda e: e["event"] == "transport" and e["kind"] == "close",
                      start=i_before, timeout_s=WAIT_S, what="the router's transport closing")
    assert daemon.running(), net.tails()
    router = _start_router(net, router_kind, router_conf, 2)

    def recovered(e: dict[str, Any]) -> bool:
        return bool(e["event"] == "health" and e["streams"]["rate"]["missing"] > 0
                    and e["checks"]["rates"] >= checks["rates"] + MIN_RATES)

    _, after = ground.wait_event(recovered, start=i_before, timeout_s=WAIT_S,
                                 what="rate messages resuming after a gap")
    assert daemon.running() and daemon.pid == daemon_pid, net.tails()
    rate = after["streams"]["rate"]
    assert rate["resets"] == 0 and after["streams"]["health"]["resets"] == 0, after
    assert rate["last_seq"] > seq_before + rate["missing"], after
    outage = [g for g in after["rate_gaps"] if g[0] >= seq_before]
    assert outage, after  # the crash shows as a jump in seq, not a restart from 0
    assert after["health"]["uptime_s"] > before["health"]["uptime_s"], after
    assert after["health"]["seq"] > before["health"]["seq"], after
    assert after["checks"]["max_residual_dps"] < 1e-9, after

    # 4. the calibration queryable across the restarted router
    ground.send_line("query")
    _, reply = ground.wait_event(lambda e: e["event"] == "calibration", timeout_s=WAIT_S,
                                 what="calibration reply")
    assert "error" not in reply, reply
    assert reply["calibration_id"] == cal_id, reply
    assert reply["model"]["name"] == "paper", reply
    assert reply["health"]["uptime_s"] >= after["health"]["uptime_s"], reply

    # orderly end: the daemon accounts for every frame it received
    ground.send_line("quit")
    ground.wait_event(lambda e: e["event"] == "final", timeout_s=WAIT_S, what="final stats")
    assert daemon.stop(sig=signal.SIGTERM) == 0, net.tails()
    summary = daemon.wait_line(r"frames in (\d+), published (\d+), dropped (\d+) (\{.*\})",
                               timeout_s=WAIT_S)
    received, published, dropped = map(int, summary.groups()[:3])
    assert received > 0 and published + dropped == received, summary[0]
    player.stop()
    router.stop()

    # 3. the gap is reported in health
    missing = (after["streams"]["rate"]["missing"] + after["streams"]["state"]["missing"]
               - missing_before)
    reported = after["health"]["drops"].get("no_subscriber", 0) - no_sub_before
    assert missing > 0 and reported > 0, after
    # equal but for messages lost in flight when the link died (the daemon cannot
    # see those) and zenoh's matching notice lagging the link's death
    assert abs(reported - missing) <= max(30, missing // 4), (reported, missing, after)
    assert "'no_subscriber': " in summary[4], summary[0]
    assert re.search(r"zenoh: lost router", "\n".join(daemon.err)), daemon.tail()
