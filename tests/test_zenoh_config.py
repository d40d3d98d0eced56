"""Zenoh session config: safe defaults checked in the config and in the sockets we hold."""

from __future__ import annotations

import ipaddress
import json
import os
import socket
import threading
from pathlib import Path
from typing import Any

import pytest
import zenoh

import streamkit
from gyrotherm import ConfigError
from gyrotherm._zenoh import (
    ACL_POLICY_ID,
    ACL_RULE_ID,
    ACL_SUBJECT_ID,
    _insert,
    is_any_interface,
    keys,
    open_session,
    session_config,
    zenoh_error_text,
)
from streamkit import dead_port, open_ephemeral, retry_on_address_in_use


# ------------------------------------------------------------------ /proc helpers
def _own_socket_inodes() -> set[int]:
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(int(target[8:-1]))
    return inodes


def _addr(hex_addr: str) -> tuple[str, int]:
    """Decode /proc/net/{tcp,udp}[6] ``ADDR:PORT`` (address in host byte order words)."""
    host, port = hex_addr.split(":")
    raw = bytes.fromhex(host)
    # each 32-bit word is little-endian on x86/arm64
    swapped = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    return str(ipaddress.ip_address(swapped)), int(port, 16)


def _own_sockets(proto: str, *, listening_only: bool) -> set[tuple[int, str, int]]:
    """(inode, address, port) of this process's ``proto`` sockets (tcp or udp, v4 and v6)."""
    own = _own_socket_inodes()
    out = set()
    for suffix in ("", "6"):
        path = f"/proc/self/net/{proto}{suffix}"
        if not os.path.exists(path):
            continue
        with open(path) as f:
            for line in f.readlines()[1:]:
                fields = line.split()
                state, inode = fields[3], int(fields[9])
                if inode in own and (not listening_only or state == "0A"):
                    out.add((inode, *_addr(fields[1])))
    return out


def test_proc_address_decoder() -> None:
    assert _addr("0100007F:1D27") == ("127.0.0.1", 7463)
    assert _addr("00000000000000000000000000000000:0050") == ("::", 80)
    assert _addr("00000000000000000000000001000000:0050") == ("::1", 80)


# ------------------------------------------------------------------ key expressions
def test_keys() -> None:
    k = keys("rover-1", "imu_0.a")
    assert (k.rate, k.state, k.health, k.calibration) == (
        "gyrotherm/rover-1/imu_0.a/rate",
        "gyrotherm/rover-1/imu_0.a/state",
        "gyrotherm/rover-1/imu_0.a/health",
        "gyrotherm/rover-1/imu_0.a/calibration",
    )
    for key in (k.rate, k.state, k.health, k.calibration):
        assert str(zenoh.KeyExpr(key)) == key  # valid and canonical for zenoh


@pytest.mark.parametrize(
    "bad", ["", "a/b", "*", "**", "a*", "$x", "a$*", "a#b", "a?b", "a b", ".", "..", "-x",
            "x" * 65, "é", "a\n"],
)  # fmt: skip
def test_bad_names_are_refused(bad: str) -> None:
    with pytest.raises(ConfigError, match=r"vehicle name .* is invalid"):
        keys(bad, "imu")
    with pytest.raises(ConfigError, match=r"sensor name .* is invalid"):
        keys("v", bad)


# ------------------------------------------------------------------ config contents
def test_zenoh_default_would_listen_on_all_interfaces() -> None:
    """Why session_config exists: zenoh's own peer default is tcp/[::]:0."""
    default = json.loads(zenoh.Config().get_json("listen/endpoints"))
    assert default["peer"] == ["tcp/[::]:0"]


def test_safe_defaults() -> None:
    c = session_config()
    assert json.loads(c.get_json("mode")) == "peer"
    assert json.loads(c.get_json("scouting/multicast/enabled")) is False
    assert json.loads(c.get_json("scouting/gossip/enabled")) is False
    assert json.loads(c.get_json("listen/endpoints")) == []
    assert json.loads(c.get_json("connect/endpoints")) == []


def test_explicit_endpoints_and_mode() -> None:
    c = session_config(mode="router", listen=["tcp/127.0.0.1:7447"],
                       connect=["tcp/127.0.0.1:7448", "tcp/localhost:7449"])  # fmt: skip
    assert json.loads(c.get_json("mode")) == "router"
    assert json.loads(c.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(c.get_json("connect/endpoints")) == [
        "tcp/127.0.0.1:7448", "tcp/localhost:7449"]  # fmt: skip


@pytest.mark.parametrize(
    ("endpoint", "any_if"),
    [
        ("tcp/0.0.0.0:7447", True), ("tcp/[::]:0", True), ("udp/0.0.0.0:7447", True),
        ("tcp/[::ffff:0.0.0.0]:1", True), ("tcp/0:7447", True),
        ("tcp/[::]:7447?iface=lo", True), ("tcp/127.0.0.1:7447", False),
        ("tcp/[::1]:7447", False), ("tcp/localhost:0", False), ("tcp/10.1.2.3:7447", False),
        ("unixsock-stream//tmp/zenoh.sock", False),
    ],
)  # fmt: skip
def test_any_interface_detection(endpoint: str, any_if: bool) -> None:
    assert is_any_interface(endpoint) is any_if
    if any_if:
        with pytest.raises(ConfigError, match=r"listens on all interfaces"):
            session_config(listen=[endpoint])
        c = session_config(listen=[endpoint], allow_any_interface=True)
        assert json.loads(c.get_json("listen/endpoints")) == [endpoint]


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"listen": ["garbage"]}, r"listen endpoint 'garbage' is invalid"),
        ({"connect": ["tcp:127.0.0.1"]}, r"connect endpoint 'tcp:127.0.0.1' is invalid"),
        ({"connect": "tcp/127.0.0.1:1"}, r"must be a list of strings"),
        ({"mode": "server"}, r"zenoh mode 'server' is invalid"),
        ({"mode": "client"}, r"client mode needs at least one connect endpoint"),
        ({"mode": "client", "connect": ["tcp/127.0.0.1:1"], "listen": ["tcp/127.0.0.1:2"]},
         r"client mode cannot listen"),
    ],
)  # fmt: skip
def test_invalid_options(kwargs: dict[str, object], pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern):
        session_config(**kwargs)  # type: ignore[arg-type]


def test_config_file_is_passed_through(tmp_path: Path) -> None:
    path = tmp_path / "zenoh.json5"
    path.write_text(
        "{\n  // deployment file\n  mode: 'client',\n"
        "  connect: { endpoints: ['tcp/192.0.2.1:7447'] },\n"
        "  scouting: { multicast: { enabled: true } },\n}\n"
    )
    c = session_config(config_file=path)
    assert json.loads(c.get_json("mode")) == "client"
    assert json.loads(c.get_json("connect/endpoints")) == ["tcp/192.0.2.1:7447"]
    assert json.loads(c.get_json("scouting/multicast/enabled")) is True  # unchanged
    with pytest.raises(ConfigError, match=r"given together with mode/listen/connect"):
        session_config(config_file=path, listen=["tcp/127.0.0.1:0"])
    with pytest.raises(ConfigError, match=r"zenoh config file .*missing.json5"):
        session_config(config_file=tmp_path / "missing.json5")


# ------------------------------------------------------------------ real sessions
def test_default_session_listens_nowhere_and_scouts_nothing() -> None:
    tcp_before = _own_sockets("tcp", listening_only=True)
    udp_before = _own_sockets("udp", listening_only=False)
    with open_session() as session:
        assert not session.is_closed()
        assert _own_sockets("tcp", listening_only=True) - tcp_before == set()
        assert _own_sockets("udp", listening_only=False) - udp_before == set()


def test_ephemeral_listen_is_loopback_only() -> None:
    before = _own_sockets("tcp", listening_only=True)
    with open_session(listen=["tcp/127.0.0.1:0"]):
        new = _own_sockets("tcp", listening_only=True) - before
        assert len(new) == 1
        (_inode, host, port) = new.pop()
        assert host == "127.0.0.1" and port > 0


def test_ephemeral_port_read_back_is_the_bound_socket() -> None:
    """The tests' race-free listener (streamkit.open_ephemeral) against /proc."""
    before = _own_sockets("tcp", listening_only=True)
    session, endpoint = open_ephemeral(session_config(listen=["tcp/127.0.0.1:0"]))
    with session:
        new = _own_sockets("tcp", listening_only=True) - before
        assert {(h, p) for _, h, p in new} == {("127.0.0.1", int(endpoint.rsplit(":", 1)[1]))}
        assert endpoint.startswith("tcp/127.0.0.1:")


def test_explicit_port_and_conflict() -> None:
    before = _own_sockets("tcp", listening_only=True)
    port, session = retry_on_address_in_use(
        lambda p: (p, open_session(listen=[f"tcp/127.0.0.1:{p}"]))
    )
    with session:
        assert {(h, p) for _, h, p in _own_sockets("tcp", listening_only=True) - before} == {
            ("127.0.0.1", port)}  # fmt: skip
        with pytest.raises(ConfigError, match=rf"cannot open zenoh session .*{port}"):
            open_session(listen=[f"tcp/127.0.0.1:{port}"])  # held by the session above


def test_port_lost_to_another_process_is_retried(monkeypatch: pytest.MonkeyPatch) -> None:
    """streamkit.retry_on_address_in_use recognises zenoh's "address in use" and retries."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        busy = int(taken.getsockname()[1])
        handed: list[int] = []
        real = streamkit.free_port

        def first_busy() -> int:
            handed.append(busy if not handed else real())
            return handed[-1]

        monkeypatch.setattr(streamkit, "free_port", first_busy)
        port, session = retry_on_address_in_use(
            lambda p: (p, open_session(listen=[f"tcp/127.0.0.1:{p}"]))
        )
        with session:
            assert handed[0] == busy and port == handed[1] != busy
        with pytest.raises(ConfigError, match="invalid"):  # other errors are not retried
            retry_on_address_in_use(lambda p: open_session(listen=[f"bogus{p}"]))


def test_free_port_is_below_the_ephemeral_range() -> None:
    with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
        low = int(f.read().split()[0])
    ports = [streamkit.free_port() for _ in range(5)]
    assert len(set(ports)) == 5 and all(10_000 <= p < low for p in ports)


def test_client_mode_without_router_fails_cleanly() -> None:
    with dead_port() as port, pytest.raises(
        ConfigError, match=r"cannot open zenoh session \(mode=client"
    ):
        open_session(mode="client", connect=[f"tcp/127.0.0.1:{port}"])


# ------------------------------------------------------------------ error messages
@pytest.mark.parametrize(
    ("raw", "clean"),
    [
        ('Json5Err(Message { msg: "unknown variant `server`", location: Some(Location { '
         'line: 1, column: 1 }) }) at /root/.cargo/git/checkouts/zenoh-9c5/cc8/zenoh/src/api/'
         'config.rs:86.', "unknown variant `server` (line 1, column 1)"),
        ("No such file or directory (os error 2) at /root/.cargo/registry/src/index/"
         "zenoh-config-1.10.2/src/lib.rs:1507.", "No such file or directory (os error 2)"),
        ("Access control not enabled due to: Found empty rule id at /x/authorization.rs:321. "
         "at /x/access_control.rs:711.", "Access control not enabled due to: Found empty rule id"),
        ("link failed (/home/u/src/zenoh/io/link.rs:10:5): refused", "link failed: refused"),
        ('Str("unknown key") at /r/config.rs:86.', "unknown key"),
        ("plain message", "plain message"),
    ],
)  # fmt: skip
def test_zenoh_error_text_strips_rust_locations(raw: str, clean: str) -> None:
    assert zenoh_error_text(raw) == clean


def _no_rust(text: str) -> None:
    assert ".rs:" not in text and ".cargo" not in text, text


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        ("{ mode: 'server' }", r"unknown variant `server`.*\(line 1, column \d+\)"),
        ("{ listen: { endpoints: 5 } }", r"invalid type: integer `5`"),
        ("{ mode: 'peer', ", r"expected identifier or string \(line 1, column 17\)"),
    ],
)  # fmt: skip
def test_bad_config_file_error_names_the_file_without_rust_paths(
    tmp_path: Path, content: str, reason: str
) -> None:
    path = tmp_path / "zenoh.json5"
    path.write_text(content)
    with pytest.raises(ConfigError, match=rf"zenoh config file '{path}': .*{reason}") as info:
        session_config(config_file=path)
    _no_rust(str(info.value))
    with pytest.raises(ConfigError, match=r"missing.json5': No such file") as info:
        session_config(config_file=tmp_path / "missing.json5")
    _no_rust(str(info.value))


def test_rejected_value_and_failed_open_carry_no_rust_paths(tmp_path: Path) -> None:
    config = zenoh.Config()
    with pytest.raises(ConfigError, match=r"demo: mode = 'server' rejected: unknown variant") as e:
        _insert(config, "mode", "server", "demo")
    _no_rust(str(e.value))
    # zenoh checks the access control only when the session opens
    path = tmp_path / "zenoh.json5"
    path.write_text(json.dumps({
        "mode": "peer", "listen": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        "access_control": {"enabled": True, "default_permission": "allow",
                           "rules": [{"id": " ", "permission": "deny", "messages": ["put"],
                                      "key_exprs": ["a/**"]}],
                           "subjects": [{"id": "s"}], "policies": [{"rules": [" "],
                                                                     "subjects": ["s"]}]},
    }))  # fmt: skip
    with pytest.raises(ConfigError, match=r"cannot open zenoh session \(config file .*: "
                                          r"Access control not enabled due to: Found empty rule id"
                       ) as e:  # fmt: skip
        open_session(config_file=path)
    _no_rust(str(e.value))
    with dead_port() as port, pytest.raises(ConfigError, match=r"Unable to connect") as e:
        open_session(mode="client", connect=[f"tcp/127.0.0.1:{port}"])
    _no_rust(str(e.value))


# ------------------------------------------------------------------ the daemon's ACL rule
def _acl(config: zenoh.Config) -> dict[str, Any]:
    acl: dict[str, Any] = json.loads(config.get_json("access_control"))
    return acl


def test_protect_adds_an_ingress_deny_rule_for_the_sensor_keys() -> None:
    k = keys("veh1", "imu0")
    assert _acl(session_config())["enabled"] is False  # only the daemon's session gets it
    acl = _acl(session_config(listen=["tcp/127.0.0.1:0"], protect=k))
    assert acl["enabled"] is True and acl["default_permission"] == "allow"
    (rule,) = acl["rules"]
    assert rule["permission"] == "deny" and rule["flows"] == ["ingress"]
    assert set(rule["messages"]) == {"put", "delete", "declare_queryable", "reply",
                                     "liveliness_token"}  # fmt: skip
    assert rule["key_exprs"] == ["gyrotherm/veh1/imu0/**"]
    (subject,) = acl["subjects"]
    assert {key for key, value in subject.items() if value is not None} == {"id"}  # everyone
    assert acl["policies"] == [{"id": ACL_POLICY_ID, "rules": [ACL_RULE_ID],
                                "subjects": [ACL_SUBJECT_ID]}]  # fmt: skip
    with open_session(listen=["tcp/127.0.0.1:0"]) as _, zenoh.open(
        session_config(listen=["tcp/127.0.0.1:0"], protect=k)
    ) as protected:  # zenoh accepts the rule
        assert not protected.is_closed()


def _file(tmp_path: Path, **extra: Any) -> Path:
    path = tmp_path / "zenoh.json5"
    path.write_text(json.dumps({
        "mode": "peer", "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}}, **extra}))
    return path


def test_protect_merges_into_a_files_own_access_control(tmp_path: Path) -> None:
    own = {"enabled": True, "default_permission": "deny",
           "rules": [{"id": "mine", "permission": "allow", "flows": ["ingress", "egress"],
                      "messages": ["put", "declare_subscriber"], "key_exprs": ["gyrotherm/**"]}],
           "subjects": [{"id": "lan", "interfaces": ["lo"]}],
           "policies": [{"id": "p", "rules": ["mine"], "subjects": ["lan"]}]}  # fmt: skip
    config = session_config(config_file=_file(tmp_path, access_control=own),
                            protect=keys("veh1", "imu0"))
    acl = _acl(config)
    assert acl["default_permission"] == "deny"  # the file's own
    assert [r["id"] for r in acl["rules"]] == ["mine", ACL_RULE_ID]
    assert [s["id"] for s in acl["subjects"]] == ["lan", ACL_SUBJECT_ID]
    assert [p["id"] for p in acl["policies"]] == ["p", ACL_POLICY_ID]
    zenoh.open(config).close()
    # a disabled block is replaced (enabling it would apply its default "deny" to all)
    off = dict(own, enabled=False)
    acl = _acl(session_config(config_file=_file(tmp_path, access_control=off),
                              protect=keys("veh1", "imu0")))
    assert acl["default_permission"] == "allow" and [r["id"] for r in acl["rules"]] == [
        ACL_RULE_ID]  # fmt: skip


def test_protect_refuses_reserved_ids_and_multicast_transports(tmp_path: Path) -> None:
    own = {"enabled": True, "default_permission": "allow",
           "rules": [{"id": ACL_RULE_ID, "permission": "deny", "messages": ["put"],
                      "key_exprs": ["x/**"]}],
           "subjects": [{"id": "s"}], "policies": [{"rules": [ACL_RULE_ID], "subjects": ["s"]}]}
    path = _file(tmp_path, access_control=own)
    with pytest.raises(ConfigError, match=rf"zenoh.json5'.*rules already has id '{ACL_RULE_ID}'"):
        session_config(config_file=path, protect=keys("veh1", "imu0"))
    session_config(config_file=path)  # without protect the file passes through unchanged
    path = _file(tmp_path, connect={"endpoints": ["udp/224.0.0.225:7448"]})
    with pytest.raises(ConfigError, match=r"connect/endpoints 'udp/224.0.0.225:7448' is a "
                                          r"multicast transport"):  # fmt: skip
        session_config(config_file=path, protect=keys("veh1", "imu0"))


@pytest.mark.parametrize("protected", [False, True])
def test_protect_applies_in_client_mode(protected: bool) -> None:
    """zenoh applies the rule in a client session too: a put from another client,
    routed to it by a router, is dropped at the protected client's ingress."""
    k = keys("veh1", "imu0")
    router, endpoint = open_ephemeral(session_config(mode="router", listen=["tcp/127.0.0.1:0"]))
    with router, zenoh.open(session_config(mode="client", connect=[endpoint],
                                           protect=k if protected else None)) as client, \
            open_session(mode="client", connect=[endpoint]) as other:  # fmt: skip
        got: list[str] = []
        client.declare_subscriber("gyrotherm/**", lambda s: got.append(str(s.key_expr)))
        client.declare_queryable("sync/q", lambda q: q.reply("sync/q", b"ok"))
        pub = other.declare_publisher(k.rate)
        querier = other.declare_querier("sync/q", timeout=10)
        # the client declared its subscriber before its queryable, on one link: once
        # the querier matches, the router knows both
        matched = threading.Event()
        listener = querier.declare_matching_listener(lambda st: st.matching and matched.set())
        assert querier.matching_status.matching or matched.wait(10)
        listener.undeclare()
        for _ in range(3):
            pub.put(b"forged")
            # the router forwards the put, then this query, on the same link: when the
            # reply is back, the client's subscriber has seen the put if it passed
            assert [r.ok is not None for r in querier.get()] == [True]
            if got:
                break
        assert got == ([] if protected else [k.rate])
