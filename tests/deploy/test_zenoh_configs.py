"""The example Zenoh configurations in deploy/zenoh/ against eclipse-zenoh itself.

* Every file parses with ``zenoh.Config.from_file`` (zenoh's own schema check
  rejects unknown keys and bad enum values, so this validates key names too).
* The project's network rules hold in each: multicast and gossip scouting
  off, explicit endpoints, nothing listening on 0.0.0.0 or [::] — read back
  from zenoh's effective configuration, where an absent ``listen`` would show
  zenoh's default ``tcp/[::]:…``.
* With certificates made by the ``openssl`` CLI in a temporary directory:
  two sessions configured from tls-mutual.json5 exchange a sample over mutual
  TLS on 127.0.0.1 while a certificate from another CA is refused; and a
  router configured from acl-router.json5 forwards the daemon's samples and
  replies to a viewer but drops a viewer's publication under gyrotherm/**.
* router.json5 requires a login and lets only the user gyrotherm-daemon publish
  (the same ACL shape by user name); client-of-router.json5 ships a placeholder
  password that gyrotherm refuses. The live spoofing checks of every shipped
  configuration are in test_spoofing.py.
"""

from __future__ import annotations

import json
import shutil
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from gyrotherm import ConfigError
from gyrotherm._zenoh import PLACEHOLDER_PASSWORD, session_config
from pkikit import make_pki, tls_files
from streamkit import open_ephemeral

DEPLOY_ZENOH = Path(__file__).resolve().parents[2] / "deploy" / "zenoh"
CONFIG_FILES = sorted(DEPLOY_ZENOH.glob("*.json5"))
WAIT_S = 10.0


def _json(config: zenoh.Config, key: str) -> Any:
    return json.loads(config.get_json(key))


def _effective(config: zenoh.Config, key: str) -> list[str]:
    """A mode-dependent endpoint list resolved for the config's own mode."""
    value = _json(config, key)
    if isinstance(value, dict):
        value = value.get(_json(config, "mode"), [])
    assert isinstance(value, list)
    return [str(item) for item in value]


def test_expected_config_files_exist() -> None:
    names = {path.name for path in CONFIG_FILES}
    assert names == {
        "peer-vehicle.json5",
        "client-of-router.json5",
        "router.json5",
        "tls-mutual.json5",
        "acl-router.json5",
    }


@pytest.mark.parametrize("path", CONFIG_FILES, ids=lambda p: p.name)
def test_config_parses_and_follows_network_rules(path: Path) -> None:
    config = zenoh.Config.from_file(str(path))
    mode = _json(config, "mode")
    assert mode in {"peer", "client", "router"}
    assert _json(config, "scouting/multicast/enabled") is False
    assert _json(config, "scouting/gossip/enabled") is False
    listen = _effective(config, "listen/endpoints")
    connect = _effective(config, "connect/endpoints")
    if mode == "client":
        assert listen == []
        assert connect, "a client needs a router endpoint"
    else:
        assert listen, f"{path.name}: explicit listen endpoints are required"
    for endpoint in listen + connect:
        protocol, _, address = endpoint.partition("/")
        assert protocol in {"tcp", "tls"}, endpoint
        host = address.rsplit(":", 1)[0]
        assert host not in {"0.0.0.0", "[::]", "::", "[::0]"}, endpoint
    for endpoint in listen:
        assert endpoint.split("/", 1)[1].startswith("127.0.0.1:"), endpoint


def test_tls_configs_require_mutual_tls_only() -> None:
    for name in ("tls-mutual.json5", "acl-router.json5"):
        config = zenoh.Config.from_file(str(DEPLOY_ZENOH / name))
        tls = _json(config, "transport/link/tls")
        assert tls["enable_mtls"] is True, name
        assert tls["root_ca_certificate"], name
        assert tls["listen_certificate"] and tls["listen_private_key"], name
        assert _json(config, "transport/link/protocols") == ["tls"], name
    tls = _json(
        zenoh.Config.from_file(str(DEPLOY_ZENOH / "tls-mutual.json5")), "transport/link/tls"
    )
    assert tls["connect_certificate"] and tls["connect_private_key"]
    assert tls["verify_name_on_connect"] is True


@pytest.mark.parametrize(
    ("name", "identity", "daemon_id"),
    [("acl-router.json5", "cert_common_names", "gyrotherm-daemon"),
     ("router.json5", "usernames", "gyrotherm-daemon")],
)  # fmt: skip
def test_acl_lets_only_the_daemon_publish_under_gyrotherm(
    name: str, identity: str, daemon_id: str
) -> None:
    acl = _json(zenoh.Config.from_file(str(DEPLOY_ZENOH / name)), "access_control")
    assert acl["enabled"] is True
    assert acl["default_permission"] == "deny"
    rules = {rule["id"]: rule for rule in acl["rules"]}
    subjects = {subject["id"]: subject for subject in acl["subjects"]}
    publishing = {"put", "delete", "declare_queryable", "reply"}
    for policy in acl["policies"]:
        for rule_id in policy["rules"]:
            rule = rules[rule_id]
            assert rule["permission"] == "allow"
            grants_publish = "ingress" in rule["flows"] and publishing & set(rule["messages"])
            if grants_publish:
                assert policy["subjects"] == ["daemon"], rule_id
    assert subjects["daemon"][identity] == [daemon_id]
    # every subject is identified by an authenticated property, never by nothing
    for subject in acl["subjects"]:
        assert subject.get(identity), subject


def test_plain_router_requires_a_login_and_the_client_file_a_real_password(
    tmp_path: Path,
) -> None:
    router = zenoh.Config.from_file(str(DEPLOY_ZENOH / "router.json5"))
    assert _json(router, "transport/auth/usrpwd/dictionary_file")
    client = zenoh.Config.from_file(str(DEPLOY_ZENOH / "client-of-router.json5"))
    usrpwd = _json(client, "transport/auth/usrpwd")
    assert usrpwd["user"] == "gyrotherm-daemon"
    assert usrpwd["password"] == PLACEHOLDER_PASSWORD
    with pytest.raises(ConfigError, match=r"client-of-router.json5.*usrpwd/password .*placeholder"):
        session_config(config_file=DEPLOY_ZENOH / "client-of-router.json5")
    edited = tmp_path / "zenoh.json5"
    edited.write_text((DEPLOY_ZENOH / "client-of-router.json5").read_text().replace(
        PLACEHOLDER_PASSWORD, "a-real-secret"))
    assert _json(session_config(config_file=edited), "transport/auth/usrpwd/password") == (
        "a-real-secret")


# --------------------------------------------------------------- live TLS tests
@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """CA + leaf certificates (EC P-256, SAN 127.0.0.1) made with the openssl CLI."""
    if shutil.which("openssl") is None:
        pytest.skip("the openssl CLI is not installed: cannot make test certificates")
    return make_pki(tmp_path_factory.mktemp("pki"),
                    ("gyrotherm-router", "gyrotherm-daemon", "gyrotherm-viewer", "gyrotherm-peer"),
                    "gyrotherm-rogue")


_tls_files = tls_files


def _tls_node(
    pki: Path, name: str, *, mode: str, listen: list[str], connect: list[str], ca: str = "test-ca"
) -> zenoh.Config:
    """tls-mutual.json5 with this node's files and endpoints."""
    config = zenoh.Config.from_file(str(DEPLOY_ZENOH / "tls-mutual.json5"))
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    _tls_files(config, pki, ca, name)
    return config


@contextmanager
def _opened(config: zenoh.Config) -> Iterator[zenoh.Session]:
    session = zenoh.open(config)
    try:
        yield session
    finally:
        session.close()


@contextmanager
def _opened_ephemeral(config: zenoh.Config) -> Iterator[tuple[zenoh.Session, str]]:
    """Open a config listening on ``tls/127.0.0.1:0``; yield it and its real endpoint."""
    session, endpoint = open_ephemeral(config)
    try:
        yield session, endpoint
    finally:
        session.close()


def _put_until(publisher: Any, payload: bytes, arrived: threading.Event) -> bool:
    """Put ``payload`` every 0.5 s until ``arrived`` is set (at most WAIT_S): a loaded
    machine may lose the first put while a new TLS link settles."""
    for _ in range(int(WAIT_S / 0.5)):
        publisher.put(payload)
        if arrived.wait(0.5):
            return True
    return False


def _wait_matching(publisher: Any) -> bool:
    """Wait until the publisher sees a matching subscriber (declarations arrived)."""
    matched = threading.Event()

    def on_status(status: Any) -> None:
        if status.matching:
            matched.set()

    listener = publisher.declare_matching_listener(on_status)
    try:
        return bool(publisher.matching_status.matching) or matched.wait(WAIT_S)
    finally:
        listener.undeclare()


def test_mutual_tls_peers_exchange_a_sample(pki: Path) -> None:
    received: list[bytes] = []
    got = threading.Event()

    def on_sample(sample: Any) -> None:
        received.append(bytes(sample.payload.to_bytes()))
        got.set()

    listener_cfg = _tls_node(
        pki, "gyrotherm-peer", mode="peer", listen=["tls/127.0.0.1:0"], connect=[]
    )
    with ExitStack() as stack:
        listener, endpoint = stack.enter_context(_opened_ephemeral(listener_cfg))
        talker_cfg = _tls_node(pki, "gyrotherm-daemon", mode="peer", listen=[], connect=[endpoint])
        talker = stack.enter_context(_opened(talker_cfg))
        subscriber = listener.declare_subscriber("gyrotherm/test/imu0/rate", on_sample)
        publisher = talker.declare_publisher("gyrotherm/test/imu0/rate")
        assert _wait_matching(publisher)
        assert _put_until(publisher, b"rate over mTLS", got)
        assert set(received) == {b"rate over mTLS"}
        subscriber.undeclare()
        publisher.undeclare()

        # A certificate signed by another CA is refused by the listener.
        rogue_cfg = _tls_node(
            pki, "gyrotherm-rogue", mode="client", listen=[], connect=[endpoint], ca="test-ca"
        )
        with pytest.raises(zenoh.ZError):
            zenoh.open(rogue_cfg).close()


def test_acl_router_drops_a_viewers_publication(pki: Path) -> None:
    router_cfg = zenoh.Config.from_file(str(DEPLOY_ZENOH / "acl-router.json5"))
    router_cfg.insert_json5("listen/endpoints", json.dumps(["tls/127.0.0.1:0"]))
    _tls_files(router_cfg, pki, "test-ca", "gyrotherm-router")
    key = "gyrotherm/veh1/imu0/rate"

    daemon_saw: list[bytes] = []
    daemon_saw_at_query: list[list[bytes]] = []
    viewer_saw: list[bytes] = []
    viewer_got_sample = threading.Event()

    def daemon_on_sample(sample: Any) -> None:
        daemon_saw.append(bytes(sample.payload.to_bytes()))

    def daemon_on_query(query: Any) -> None:
        daemon_saw_at_query.append(list(daemon_saw))
        query.reply(query.key_expr, b'{"schema": "gyrotherm.calibration"}')

    def viewer_on_sample(sample: Any) -> None:
        viewer_saw.append(bytes(sample.payload.to_bytes()))
        viewer_got_sample.set()

    with ExitStack() as stack:
        _router, endpoint = stack.enter_context(_opened_ephemeral(router_cfg))

        def client(name: str) -> zenoh.Config:
            return _tls_node(pki, name, mode="client", listen=[], connect=[endpoint])

        daemon = stack.enter_context(_opened(client("gyrotherm-daemon")))
        viewer = stack.enter_context(_opened(client("gyrotherm-viewer")))
        viewer.declare_subscriber("gyrotherm/**", viewer_on_sample)

        # Allowed: the daemon publishes, the viewer receives. The daemon has no
        # subscriber of its own yet, so "matching" can only mean that the router
        # announced the viewer's subscription.
        daemon_pub = daemon.declare_publisher(key)
        assert _wait_matching(daemon_pub)
        assert _put_until(daemon_pub, b"from daemon", viewer_got_sample)
        assert set(viewer_saw) == {b"from daemon"}

        daemon.declare_subscriber("gyrotherm/**", daemon_on_sample)
        daemon.declare_queryable("gyrotherm/veh1/imu0/calibration", daemon_on_query)

        # The daemon declared its subscriber before its queryable on the same
        # link: once the viewer's query is answered, the router knows both.
        def ask() -> list[bytes]:
            replies = viewer.get("gyrotherm/veh1/imu0/calibration", timeout=WAIT_S)
            return [bytes(r.ok.payload.to_bytes()) for r in replies if r.ok is not None]

        for _ in range(int(WAIT_S / 0.5)):
            if ask():
                break
        assert daemon_saw_at_query, "the router never forwarded the viewer's query"

        # Denied: the viewer publishes under gyrotherm/**, then queries again. The
        # put travelled the same link just before the query: had the router
        # forwarded it, the daemon would have seen it when the query arrived.
        viewer_pub = viewer.declare_publisher(key)
        viewer_pub.put(b"forged by viewer")
        assert ask() == [b'{"schema": "gyrotherm.calibration"}']
        assert all(seen == [] for seen in daemon_saw_at_query)
        assert b"forged by viewer" not in daemon_saw
