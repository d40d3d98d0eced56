"""Spoofing: another local process cannot pass for the daemon, with any shipped configuration.

For every configuration a Subscriber can use (the bench TOML's ``[zenoh]`` table,
and each deploy/zenoh file the deploy/config TOMLs install as
``/etc/gyrotherm/zenoh.json5``, with its router where it has one), this starts the
real :class:`~gyrotherm.daemon.Daemon` in-process on a virtual CAN bus fed with
frames, a :class:`~gyrotherm.client.Subscriber`, and rogue sessions in client and
in peer mode (also router mode on the daemon's plain TCP endpoint) connected to the
daemon's endpoint or to the router. Each rogue
publishes valid msgpack rate/state/health messages claiming 999 °/s on the
daemon's keys (exact keys and wildcards) and declares calibration queryables
(exact key and ``**``) answering with a forged calibration id.

Checks, in the same test: the Subscriber keeps receiving the daemon's genuine
messages (positive control), receives 0 forged ones, and every calibration query
returns the daemon's calibration id. Synchronisation is by events, not sleeps:
after each burst the rogue queries the daemon's calibration over the same link
(the daemon, or the router, handled the burst before answering), then the test
waits for a genuine rate the daemon published after that answer — any forwarded
forged message would have reached the Subscriber before it.
``test_detector_sees_spoofing_without_protection`` shows the same harness does
count forged messages when the daemon's access-control rule is left out.
Routers: eclipse-zenoh in router mode, and zenohd when it is on PATH.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import threading
import time
import tomllib
import uuid
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import zenoh

import gyrotherm._zenoh as gz
from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, RateSample, TemperatureSample
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    RateMessage,
    StateMessage,
    encode_calibration_info,
    encode_health,
    encode_rate,
    encode_state,
)
from gyrotherm.codecs._wire_decode import decode_calibration_info
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.daemon import Daemon, parse_config
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs
from pkikit import make_pki, tls_files
from streamkit import free_port, open_ephemeral, stop_process

ROOT = Path(__file__).resolve().parents[2]
DEPLOY_ZENOH = ROOT / "deploy" / "zenoh"
BENCH_TOML = ROOT / "examples" / "bench-socketcand.toml"
VEHICLE, SENSOR = "bench", "imu0"
FORGED_DPS = 999.0
FORGED_ID = "forged-calibration"
BURSTS = 3
PER_BURST = 20  # forged messages per key, per rogue, per burst
WAIT_S = 20.0  # bound for 2 shared cores; never reached when things work
PASSWORDS = {"gyrotherm-daemon": "daemon-secret-7f3a", "gyrotherm-viewer": "viewer-secret-91c2"}
LOCAL = "tcp/127.0.0.1:7447"

Opener = Callable[[], zenoh.Session]


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    runs = chamber_runs([5, 20, 60], seed=8, rate_hz=1.0, hold_s=1200)
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    cal: Calibration = fit([features(r, est) for r in runs], "paper", estimator=est)
    return cal.save(tmp_path_factory.mktemp("cal") / "imu0.calibration.json")


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("openssl") is None:
        pytest.skip("the openssl CLI is not installed: cannot make test certificates")
    return make_pki(tmp_path_factory.mktemp("pki"),
                    ("gyrotherm-router", "gyrotherm-daemon", "gyrotherm-viewer"),
                    "gyrotherm-daemon-rogue")


# ------------------------------------------------------------------ config files
def _config(text: str) -> zenoh.Config:
    return zenoh.Config.from_json5(text)


def _set(config: zenoh.Config, key: str, value: object) -> zenoh.Config:
    config.insert_json5(key, json.dumps(value))
    return config


def _write(config: zenoh.Config, path: Path) -> Path:
    path.write_text(str(config), encoding="utf-8")  # zenoh's own JSON of the config
    return path


def _shipped(name: str, *, endpoint: str | None = None) -> str:
    """A shipped deploy/zenoh file's text with its loopback endpoint replaced."""
    text = (DEPLOY_ZENOH / name).read_text(encoding="utf-8")
    if endpoint is not None:
        local = LOCAL.replace("tcp/", f"{endpoint.split('/', 1)[0]}/")
        assert text.count(f'"{local}"') == 1, f"{name}: expected {local!r} once"
        text = text.replace(f'"{local}"', f'"{endpoint}"')
    return text


def _client_of_router(router: str, user: str, password: str) -> zenoh.Config:
    text = _shipped("client-of-router.json5", endpoint=router)
    assert text.count('"gyrotherm-daemon"') == 1 and text.count(gz.PLACEHOLDER_PASSWORD) == 1
    text = text.replace('"gyrotherm-daemon"', json.dumps(user))
    return _config(text.replace(gz.PLACEHOLDER_PASSWORD, password))


def _tls_node(pki: Path, name: str, *, mode: str, listen: list[str], connect: list[str],
              ca: str = "test-ca") -> zenoh.Config:  # fmt: skip
    """tls-mutual.json5 with this node's certificate and endpoints."""
    config = _config(_shipped("tls-mutual.json5"))
    _set(config, "mode", mode)
    _set(config, "listen/endpoints", listen)
    _set(config, "connect/endpoints", connect)
    tls_files(config, pki, ca, name)
    return config


def _plain(mode: str, connect: str) -> zenoh.Config:
    """A rogue's own session: no scouting, no listener, connected to ``connect``."""
    return gz.session_config(mode=mode, connect=[connect])  # type: ignore[arg-type]


# ------------------------------------------------------------------ routers
@contextmanager
def _router(kind: str, config: zenoh.Config, tmp: Path) -> Iterator[str]:
    """A router from ``config`` (listen endpoint ``<proto>/127.0.0.1:0`` for
    eclipse-zenoh); yield the endpoint it listens on."""
    listen = json.loads(config.get_json("listen/endpoints"))
    listen = listen.get("router", []) if isinstance(listen, dict) else listen
    proto = listen[0].split("/", 1)[0]
    if kind == "eclipse-zenoh":
        _set(config, "listen/endpoints", [f"{proto}/127.0.0.1:0"])
        session, endpoint = open_ephemeral(config)
        try:
            yield endpoint
        finally:
            session.close()
        return
    zenohd = shutil.which("zenohd")
    if zenohd is None:
        pytest.skip("zenohd is not on PATH: the eclipse-zenoh variant runs the same router "
                    "engine (install zenohd to run this one too)")
    endpoint = f"{proto}/127.0.0.1:{free_port()}"
    _set(config, "listen/endpoints", [endpoint])
    path = _write(config, tmp / f"zenohd-{uuid.uuid4().hex[:6]}.json5")
    log = (tmp / "zenohd.log").open("w")
    proc = subprocess.Popen([zenohd, "-c", str(path)], stdout=log, stderr=subprocess.STDOUT,
                            env={"RUST_LOG": "info", "PATH": "/usr/bin:/bin"})
    try:
        yield endpoint
    finally:
        stop_process(proc)
        log.close()


def _wait_open(open_config: Callable[[], zenoh.Config], what: str) -> zenoh.Session:
    """Open a client session, retrying while its router (a zenohd just started)
    does not accept connections yet; each attempt waits up to 2 s (connect/timeout_ms)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        config = _set(open_config(), "connect/timeout_ms", 2000)
        try:
            return zenoh.open(config)
        except zenoh.ZError as exc:
            if time.monotonic() > deadline:
                raise AssertionError(f"{what} could not connect within {WAIT_S} s: "
                                     f"{gz.zenoh_error_text(exc)}") from exc


# ------------------------------------------------------------------ scenarios
@dataclass
class Scenario:
    """One deployment: the daemon's [zenoh] table, the Subscriber's session, rogues."""

    daemon_zenoh: dict[str, Any]
    subscriber: Opener
    rogues: dict[str, Opener]
    #: rogues without valid credentials: they must not even get a link
    refused: dict[str, Callable[[], zenoh.Config]] = field(default_factory=dict)


def _bench_toml(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
    table = dict(tomllib.loads(BENCH_TOML.read_text(encoding="utf-8"))["zenoh"])
    assert table["listen"] == [LOCAL], "the example's endpoint changed: update this test"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    table["listen"] = [endpoint]
    return Scenario(
        daemon_zenoh=table,
        subscriber=lambda: gz.open_session(connect=[endpoint]),  # Subscriber's default
        rogues={m: (lambda m=m: zenoh.open(_plain(m, endpoint)))
                for m in ("client", "peer", "router")},
    )


def _peer_vehicle(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    path = tmp / "peer-vehicle.json5"
    path.write_text(_shipped("peer-vehicle.json5", endpoint=endpoint), encoding="utf-8")
    return Scenario(
        daemon_zenoh={"config": str(path)},
        subscriber=lambda: gz.open_session(connect=[endpoint]),
        rogues={m: (lambda m=m: zenoh.open(_plain(m, endpoint)))
                for m in ("client", "peer", "router")},
    )


def _peer_vehicle_own_acl(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
    """peer-vehicle.json5 with an access_control block of the user's own (default
    allow, denying egress to a test subject): gyrotherm merges its rule into it."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    config = _config(_shipped("peer-vehicle.json5", endpoint=endpoint))
    _set(config, "access_control", {
        "enabled": True, "default_permission": "allow",
        "rules": [{"id": "no-debug-out", "permission": "deny", "flows": ["egress"],
                   "messages": ["put"], "key_exprs": ["debug/**"]}],
        "subjects": [{"id": "all"}],
        "policies": [{"id": "users-own", "rules": ["no-debug-out"], "subjects": ["all"]}],
    })  # fmt: skip
    return Scenario(
        daemon_zenoh={"config": str(_write(config, tmp / "own-acl.json5"))},
        subscriber=lambda: gz.open_session(connect=[endpoint]),
        rogues={m: (lambda m=m: zenoh.open(_plain(m, endpoint)))
                for m in ("client", "peer", "router")},
    )


def _tls_peer(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
    """tls-mutual.json5 as shipped (the daemon a peer listening on TLS); the viewer
    and the rogues hold certificates of the same CA (CN gyrotherm-viewer)."""
    endpoint = f"tls/127.0.0.1:{free_port()}"
    daemon = _tls_node(pki, "gyrotherm-daemon", mode="peer", listen=[endpoint], connect=[])
    path = _write(daemon, tmp / "tls-peer.json5")

    def node(mode: str, name: str = "gyrotherm-viewer", ca: str = "test-ca") -> zenoh.Config:
        return _tls_node(pki, name, mode=mode, listen=[], connect=[endpoint], ca=ca)

    return Scenario(
        daemon_zenoh={"config": str(path)},
        subscriber=lambda: zenoh.open(node("client")),
        rogues={m: (lambda m=m: zenoh.open(node(m))) for m in ("client", "peer")},
        refused={"client, certificate of another CA": lambda: node(
            "client", "gyrotherm-daemon-rogue", "test-ca")},
    )


def _plain_router(kind: str, *, router_acl: bool = True
                  ) -> Callable[[ExitStack, Path, Path], Scenario]:  # fmt: skip
    def build(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
        users = tmp / "gyrotherm-users.txt"
        users.write_text("".join(f"{u}:{p}\n" for u, p in PASSWORDS.items()), encoding="utf-8")
        router = _config(_shipped("router.json5"))
        _set(router, "transport/auth/usrpwd/dictionary_file", str(users))
        if not router_acl:  # the harness's control only
            _set(router, "access_control/enabled", False)
        endpoint = stack.enter_context(_router(kind, router, tmp))

        def login(user: str, password: str, mode: str = "client") -> zenoh.Config:
            return _set(_client_of_router(endpoint, user, password), "mode", mode)

        # the shipped connect/timeout_ms (20 s) lets the daemon wait for a zenohd starting
        daemon_file = _write(login("gyrotherm-daemon", PASSWORDS["gyrotherm-daemon"]),
                             tmp / "client-of-router.json5")
        viewer = PASSWORDS["gyrotherm-viewer"]
        return Scenario(
            daemon_zenoh={"config": str(daemon_file)},
            subscriber=lambda: _wait_open(lambda: login("gyrotherm-viewer", viewer), "viewer"),
            rogues={f"{m} as gyrotherm-viewer": (
                lambda m=m: _wait_open(lambda: login("gyrotherm-viewer", viewer, m), "rogue"))
                for m in ("client", "peer")},
            refused={
                "client without credentials": lambda: _plain("client", endpoint),
                "peer without credentials": lambda: _plain("peer", endpoint),
                "client, gyrotherm-daemon with a wrong password": lambda: login(
                    "gyrotherm-daemon", "guessed"),
            },
        )

    return build


def _acl_router(kind: str) -> Callable[[ExitStack, Path, Path], Scenario]:
    def build(stack: ExitStack, tmp: Path, pki: Path) -> Scenario:
        router = _config(_shipped("acl-router.json5"))
        tls_files(router, pki, "test-ca", "gyrotherm-router")
        endpoint = stack.enter_context(_router(kind, router, tmp))

        def node(name: str, mode: str = "client", ca: str = "test-ca") -> zenoh.Config:
            return _tls_node(pki, name, mode=mode, listen=[], connect=[endpoint], ca=ca)

        daemon = _set(node("gyrotherm-daemon"), "connect/timeout_ms", int(WAIT_S * 1000))
        return Scenario(
            daemon_zenoh={"config": str(_write(daemon, tmp / "tls-client.json5"))},
            subscriber=lambda: _wait_open(lambda: node("gyrotherm-viewer"), "viewer"),
            rogues={f"{m} as gyrotherm-viewer": (
                lambda m=m: _wait_open(lambda: node("gyrotherm-viewer", m), "rogue"))
                for m in ("client", "peer")},
            refused={"client, gyrotherm-daemon CN from another CA": lambda: node(
                "gyrotherm-daemon-rogue")},
        )

    return build


SCENARIOS: dict[str, Callable[[ExitStack, Path, Path], Scenario]] = {
    "examples/bench-socketcand.toml": _bench_toml,
    "peer-vehicle.json5": _peer_vehicle,
    "peer-vehicle.json5 with the user's own access_control": _peer_vehicle_own_acl,
    "tls-mutual.json5 (peer)": _tls_peer,
    "router.json5+client-of-router.json5 (eclipse-zenoh)": _plain_router("eclipse-zenoh"),
    "router.json5+client-of-router.json5 (zenohd)": _plain_router("zenohd"),
    "acl-router.json5+tls-mutual.json5 (eclipse-zenoh)": _acl_router("eclipse-zenoh"),
    "acl-router.json5+tls-mutual.json5 (zenohd)": _acl_router("zenohd"),
}


# ------------------------------------------------------------------ the daemon
@contextmanager
def _running_daemon(zenoh_table: dict[str, Any], calibration: Path, tmp: Path
                    ) -> Iterator[Daemon]:  # fmt: skip
    """The daemon in a thread, fed rate and temperature frames on a virtual bus
    (~100 rate frames/s) until the block ends."""
    channel = f"spoof-{uuid.uuid4().hex[:8]}"
    cfg = parse_config({
        "vehicle": VEHICLE, "sensor": SENSOR, "calibration": str(calibration),
        "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": zenoh_table,
    }, base_dir=tmp)  # fmt: skip
    daemon = Daemon(cfg)
    failure: list[BaseException] = []

    def run() -> None:
        try:
            daemon.run()
        except BaseException as exc:
            failure.append(exc)
            daemon.ready.set()

    thread = threading.Thread(target=run, name="daemon", daemon=True)
    thread.start()
    assert daemon.ready.wait(WAIT_S), "daemon not ready"
    assert not failure, f"daemon failed to start: {failure[0]!r}"
    stop = threading.Event()

    def feed() -> None:
        encoder = FrameEncoder()
        with open_bus(interface="virtual", channel=channel) as bus:
            t0, k = time.monotonic(), 0
            while not stop.wait(0.01):
                t = time.monotonic() - t0
                if k % 10 == 0:
                    bus.send(encoder.encode_temperature(TemperatureSample(t, 30.0)))
                bus.send(encoder.encode_rate(RateSample(t, 0.1, -0.2, 0.3)))
                k += 1

    feeder = threading.Thread(target=feed, name="can-feed", daemon=True)
    feeder.start()
    try:
        yield daemon
    finally:
        stop.set()
        feeder.join(WAIT_S)
        daemon.stop()
        thread.join(WAIT_S)


# ------------------------------------------------------------------ the observer
class Observed:
    """What the Subscriber delivered, split into genuine and forged."""

    def __init__(self) -> None:
        self.lock = threading.Condition()
        self.genuine_rates = self.forged_rates = 0
        self.genuine_states = self.forged_states = 0
        self.genuine_healths = self.forged_healths = 0
        self.last_genuine_rate_time = 0.0

    def on_rate(self, m: RateMessage) -> None:
        with self.lock:
            if max(abs(v) for v in m.rate_dps) >= FORGED_DPS / 2:
                self.forged_rates += 1
            else:
                self.genuine_rates += 1
                self.last_genuine_rate_time = max(self.last_genuine_rate_time, m.receive_time_s)
            self.lock.notify_all()

    def on_state(self, m: StateMessage) -> None:
        with self.lock:
            if max(abs(v) for v in m.bias_dps) >= FORGED_DPS / 2:
                self.forged_states += 1
            else:
                self.genuine_states += 1
            self.lock.notify_all()

    def on_health(self, m: HealthMessage) -> None:
        with self.lock:
            if m.calibration_id == FORGED_ID:
                self.forged_healths += 1
            else:
                self.genuine_healths += 1
            self.lock.notify_all()

    def forged(self) -> int:
        with self.lock:
            return self.forged_rates + self.forged_states + self.forged_healths

    def wait(self, predicate: Callable[[Observed], bool], what: str) -> None:
        with self.lock:
            assert self.lock.wait_for(lambda: predicate(self), WAIT_S), \
                f"timed out waiting for {what}: {vars(self)}"


# ------------------------------------------------------------------ the rogue
def _forged_payloads(n: int) -> list[tuple[str, bytes]]:
    now = time.time()
    bad = (FORGED_DPS, FORGED_DPS, FORGED_DPS)
    out = []
    for seq in range(n):
        out.append(("rate", encode_rate(RateMessage(seq, seq * 0.01, now, bad, bad, bad))))
        out.append(("state", encode_state(StateMessage(seq, seq * 0.1, now, 30.0, 0.1, 0.0,
                                                       0.1, bad))))  # fmt: skip
        out.append(("health", encode_health(HealthMessage(
            seq, seq * 0.1, now, 1.0, 999_999, 999_999, {}, calibration_id=FORGED_ID))))
    return out


FORGED_INFO = encode_calibration_info(CalibrationInfo(FORGED_ID, None, None))


def _arm_rogue(session: zenoh.Session) -> dict[str, Any]:
    """Declare the rogue's publishers and calibration queryables; return the publishers."""
    base = f"gyrotherm/{VEHICLE}/{SENSOR}"

    def on_query(query: zenoh.Query) -> None:
        for key in (f"{base}/calibration", f"gyrotherm/{VEHICLE}/*/calibration"):
            try:
                query.reply(key, FORGED_INFO)
            except zenoh.ZError:  # a key zenoh itself refuses to reply on
                pass

    session.declare_queryable(f"{base}/calibration", on_query)
    session.declare_queryable("**", on_query)
    pubs: dict[str, Any] = {k: session.declare_publisher(f"{base}/{k}")
                            for k in ("rate", "state", "health")}  # fmt: skip
    pubs["wild-rate"] = session.declare_publisher(f"gyrotherm/{VEHICLE}/*/rate")
    return pubs


def _daemon_reply(session: zenoh.Session, daemon_id: str) -> bool:
    """Query the calibration (round trip over the rogue's link); True when the
    daemon's own answer came back. Asked again (bounded) while a session that just
    connected has not learnt the daemon's queryable yet."""
    key = f"gyrotherm/{VEHICLE}/{SENSOR}/calibration"
    pause = threading.Event()  # never set: a bounded pause between two asks
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        ids = []
        # no consolidation: the rogue's own queryables answer too, on the same key
        for reply in session.get(key, target=zenoh.QueryTarget.ALL,
                                 consolidation=zenoh.ConsolidationMode.NONE, timeout=WAIT_S):
            if reply.ok is not None:
                try:
                    ids.append(
                        decode_calibration_info(reply.ok.payload.to_bytes()).calibration_id)
                except Exception:  # a forged or foreign payload: not the daemon's
                    continue
        if daemon_id in ids:
            return True
        pause.wait(0.1)
    return False


# ------------------------------------------------------------------ the check
def _check(scenario: Scenario, calibration: Path, tmp: Path, stack: ExitStack) -> dict[str, int]:
    daemon = stack.enter_context(_running_daemon(scenario.daemon_zenoh, calibration, tmp))
    daemon_id = daemon._calibration_id
    assert daemon_id and daemon_id != FORGED_ID
    seen = Observed()
    sub_session = scenario.subscriber()
    stack.callback(sub_session.close)
    sub = stack.enter_context(Subscriber(VEHICLE, SENSOR, session=sub_session,
                                         on_rate=seen.on_rate, on_state=seen.on_state,
                                         on_health=seen.on_health))  # fmt: skip
    seen.wait(lambda o: o.genuine_rates and o.genuine_states and o.genuine_healths,
              "the daemon's first messages")

    for what, make in scenario.refused.items():
        try:
            session = zenoh.open(_set(make(), "connect/timeout_ms", 2000))
        except zenoh.ZError:
            continue  # refused at open: the expected outcome for a client
        stack.callback(session.close)
        assert session.info.transports() == [], f"{what} got a link"

    rogues = {name: open_rogue() for name, open_rogue in scenario.rogues.items()}
    for session in rogues.values():
        stack.callback(session.close)
    publishers = {name: _arm_rogue(s) for name, s in rogues.items()}
    sent = 0
    for _ in range(BURSTS):
        for name, session in rogues.items():
            for key, payload in _forged_payloads(PER_BURST):
                publishers[name][key].put(payload)
                sent += 1
            publishers[name]["wild-rate"].put(_forged_payloads(1)[0][1])
            sent += 1
            # the daemon (or router) handled the burst before it answered this
            assert _daemon_reply(session, daemon_id), f"rogue {name} is not connected"
        answered = time.time()
        seen.wait(lambda o, t=answered: o.last_genuine_rate_time > t,
                  "a genuine rate published after the rogues' bursts")
        assert seen.forged() == 0, f"forged messages delivered: {vars(seen)}"

    for _ in range(5):
        assert sub.query_calibration(timeout_s=WAIT_S).calibration_id == daemon_id
    # Every reply on the exact key is the daemon's (forged wildcard-key replies may
    # arrive; query_calibration ignores them, checked above).
    assert set(_exact_key_reply_ids(sub_session)) == {daemon_id}
    stats = sub.stats()
    assert stats.rate.undecodable == stats.state.undecodable == stats.health.undecodable == 0
    assert seen.forged() == 0
    assert seen.genuine_rates > 0 and seen.genuine_states > 0 and seen.genuine_healths > 0
    return {"sent": sent, "genuine_rates": seen.genuine_rates}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SCENARIOS))
def test_no_spoofing(name: str, tmp_path: Path, calibration_file: Path,
                     request: pytest.FixtureRequest) -> None:  # fmt: skip
    pki = request.getfixturevalue("pki") if "tls" in name else tmp_path
    with ExitStack() as stack:
        scenario = SCENARIOS[name](stack, tmp_path, pki)
        counts = _check(scenario, calibration_file, tmp_path, stack)
    assert counts["sent"] == BURSTS * len(scenario.rogues) * (3 * PER_BURST + 1)


@pytest.mark.parametrize("unprotected", ["daemon without its rule", "router without its ACL"])
def test_detector_sees_spoofing_without_protection(
    unprotected: str, tmp_path: Path, calibration_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Control for the harness: without the daemon's access-control rule (the
    situation testers found, bench config) or without the router's ACL, the
    client-mode rogue's messages reach the Subscriber and the check above fails."""
    with ExitStack() as stack:
        if unprotected.startswith("daemon"):
            monkeypatch.setattr(gz, "protect_keys", lambda config, keys, source: config)
            scenario = _bench_toml(stack, tmp_path, tmp_path)
        else:
            scenario = _plain_router("eclipse-zenoh", router_acl=False)(stack, tmp_path, tmp_path)
        scenario.rogues = {k: v for k, v in scenario.rogues.items() if k.startswith("client")}
        scenario.refused = {}
        with pytest.raises(AssertionError, match=r"forged messages delivered"):
            _check(scenario, calibration_file, tmp_path, stack)


def _exact_key_reply_ids(session: zenoh.Session) -> list[str]:
    key = f"gyrotherm/{VEHICLE}/{SENSOR}/calibration"
    return [decode_calibration_info(r.ok.payload.to_bytes()).calibration_id
            for r in session.get(key, target=zenoh.QueryTarget.ALL,
                                 consolidation=zenoh.ConsolidationMode.NONE, timeout=WAIT_S)
            if r.ok is not None and str(r.ok.key_expr) == key]  # fmt: skip


@pytest.mark.parametrize("protected", [False, True])
def test_forged_calibration_reply_reaches_the_subscriber_only_without_protection(
    protected: bool, tmp_path: Path, calibration_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Control for the calibration half of the check: without the daemon's rule a
    client-mode rogue's queryable answers the subscriber's query on the exact key."""
    if not protected:
        monkeypatch.setattr(gz, "protect_keys", lambda config, keys, source: config)
    with ExitStack() as stack:
        scenario = _bench_toml(stack, tmp_path, tmp_path)
        daemon = stack.enter_context(
            _running_daemon(scenario.daemon_zenoh, calibration_file, tmp_path))
        viewer = scenario.subscriber()
        stack.callback(viewer.close)
        rogue = scenario.rogues["client"]()
        stack.callback(rogue.close)
        _arm_rogue(rogue)
        # declarations precede the query on the rogue's link: the daemon knows them now
        assert _daemon_reply(rogue, daemon._calibration_id)
        assert _daemon_reply(viewer, daemon._calibration_id)  # the viewer is connected
        ids = _exact_key_reply_ids(viewer)
        assert daemon._calibration_id in ids
        assert (FORGED_ID in ids) is not protected, ids


def test_every_shipped_configuration_is_covered() -> None:
    """The deploy/config TOMLs install one of deploy/zenoh/*.json5 as the daemon's
    Zenoh file; the examples carry their own [zenoh] table: each has a scenario."""
    for toml in sorted((ROOT / "deploy" / "config").glob("*.toml")):
        table = tomllib.loads(toml.read_text(encoding="utf-8"))["zenoh"]
        assert table == {"config": "/etc/gyrotherm/zenoh.json5"}, toml.name
    examples = sorted(ROOT.glob("examples/*.toml"))
    assert examples == [BENCH_TOML]
    covered = " ".join(SCENARIOS)
    for path in DEPLOY_ZENOH.glob("*.json5"):
        assert path.name in covered, path.name
    assert re.search(r"\(zenohd\)", covered) and re.search(r"\(eclipse-zenoh\)", covered)
