"""``gyrotherm record --ros2``: daemon → Zenoh → record → rmw_zenoh layout, read by a plain
zenoh session as a ROS 2 subscriber would see it: payloads decoded by rosbags' CDR
deserialiser, attachments by zenoh-ext's deserialiser, liveliness tokens parsed field
by field (rmw_zenoh's design doc) with type hashes recomputed by rosbags."""

from __future__ import annotations

import json
import math
import queue
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore
from zenoh.ext import Int64, z_deserialize

from gyrotherm._zenoh import session_config
from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.client._record import record_main
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.codecs._wire import RateMessage, StateMessage
from streamkit import cli_process, dead_port, open_ephemeral, run_frames, stdout_after_sigterm

TIMEOUT_S = 20.0
DEG = math.pi / 180
STORE = get_typestore(Stores.ROS2_JAZZY)
IMU, TEMP = "sensor_msgs/msg/Imu", "sensor_msgs/msg/Temperature"
VEC, DIAG = "geometry_msgs/msg/Vector3Stamped", "diagnostic_msgs/msg/DiagnosticArray"
DDS = {IMU: "sensor_msgs::msg::dds_::Imu_", TEMP: "sensor_msgs::msg::dds_::Temperature_",
       VEC: "geometry_msgs::msg::dds_::Vector3Stamped_",
       DIAG: "diagnostic_msgs::msg::dds_::DiagnosticArray_"}
#: every channel record publishes, in order (entity ids 1…7), with its type
TOPIC_TYPES = (("imu", IMU), ("imu_raw", IMU), ("temperature", TEMP), ("delta_t", TEMP),
               ("bias", VEC), ("state", DIAG), ("health", DIAG))
N_TOKENS = 1 + len(TOPIC_TYPES)


class Listener:
    """A plain zenoh session listening on loopback: data on ``<domain>/**``, liveliness
    tokens on ``@ros2_lv/**`` (PUT/DELETE events, with history)."""

    def __init__(self, domain: int) -> None:
        self.session, self.endpoint = open_ephemeral(session_config(listen=["tcp/127.0.0.1:0"]))
        self.data: queue.Queue[tuple[str, bytes, bytes | None]] = queue.Queue()
        self.tokens: queue.Queue[tuple[Any, str]] = queue.Queue()
        self._subs = [
            self.session.declare_subscriber(f"{domain}/**", lambda s: self.data.put(
                (str(s.key_expr), s.payload.to_bytes(),
                 None if s.attachment is None else s.attachment.to_bytes()))),
            self.session.liveliness().declare_subscriber(
                "@ros2_lv/**", lambda s: self.tokens.put((s.kind, str(s.key_expr))),
                history=True),
        ]  # fmt: skip

    def token_events(self, kind: Any, n: int) -> list[str]:
        out: list[str] = []
        deadline = time.monotonic() + TIMEOUT_S
        while len(out) < n:
            k, key = self.tokens.get(timeout=max(0.0, deadline - time.monotonic()))
            if k == kind:
                out.append(key)
        return out

    def samples(self, n: int) -> list[tuple[str, bytes, bytes | None]]:
        deadline = time.monotonic() + TIMEOUT_S
        out = [self.data.get(timeout=max(0.0, deadline - time.monotonic())) for _ in range(n)]
        assert self.data.empty()
        return out

    def alive_tokens(self) -> list[str]:
        return sorted(str(r.ok.key_expr) for r in
                      self.session.liveliness().get("@ros2_lv/**", timeout=2.0)
                      if r.ok is not None)  # fmt: skip


@contextmanager
def listener(domain: int) -> Iterator[Listener]:
    lis = Listener(domain)
    try:
        yield lis
    finally:
        lis.session.close()


def _check_tokens(tokens: list[str], *, domain: int, zid: str, ns: str, node: str,
                  sensor: str) -> dict[str, list[str]]:  # fmt: skip
    """Parse every token per rmw_zenoh docs/design.md "Graph Cache"; by topic."""
    parts = [t.split("/") for t in tokens]
    nodes = [p for p in parts if p[5] == "NN"]
    pubs = {p[9]: p for p in parts if p[5] == "MP"}
    assert len(nodes) == 1 and len(pubs) == len(TOPIC_TYPES) == len(parts) - 1
    mns = ns.replace("/", "%")
    assert nodes[0] == ["@ros2_lv", str(domain), zid, "0", "0", "NN", "%", mns, node]
    base = "%".join(["", *ns.strip("/").split("/")]) if ns != "/" else ""
    want = {f"{base}%gyrotherm%{sensor}%{t}": ty for t, ty in TOPIC_TYPES}
    assert set(pubs) == set(want)
    for topic, p in pubs.items():
        assert p[:9] == ["@ros2_lv", str(domain), zid, "0", p[4], "MP", "%", mns, node]
        assert p[10:] == [DDS[want[topic]], STORE.hash_rihs01(want[topic]), "::,10:,:,:,,"]
    assert sorted(int(p[4]) for p in pubs.values()) == list(range(1, len(TOPIC_TYPES) + 1))
    return {topic: p for topic, p in pubs.items()}


def _gid(token: list[str]) -> bytes:
    """XXH3-128 of the token's key expression, low64 LE then high64 LE (the canonical
    digest is high64 then low64, big-endian: reversed)."""
    return xxhash.xxh3_128("/".join(token).encode()).digest()[::-1]


def test_ros2_end_to_end(daemon: tuple[str, int], runs: list[Run],
                         capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    channel, port = daemon
    run = runs[1].slice(0, 120)
    frames = list(run_frames(run, FrameEncoder()))
    ready, result = threading.Event(), {}
    rates: list[RateMessage] = []
    states: list[StateMessage] = []
    with listener(0) as lis, Subscriber(
            "testcar", "imu0", connect=[f"tcp/127.0.0.1:{port}"], on_rate=rates.append,
            on_state=states.append) as sub, \
            open_bus(interface="virtual", channel=channel) as bus:  # fmt: skip
        argv = ["--vehicle", "testcar", "--sensor", "imu0", "--connect", f"tcp/127.0.0.1:{port}",
                "--connect", lis.endpoint, "--ros2", "--count", str(len(run)),
                "--frame-id", "gyro_link", "--json", "--stamp", "sensor"]  # fmt: skip
        rec = threading.Thread(target=lambda: result.update(
            code=record_main(argv, on_ready=lambda _port: ready.set())))
        rec.start()
        assert ready.wait(TIMEOUT_S)
        declared = lis.token_events(zenoh.SampleKind.PUT, N_TOKENS)
        assert sorted(declared) == lis.alive_tokens()
        assert sub.wait_for(lambda s: s.health.received >= 2, timeout_s=TIMEOUT_S)
        t_before = time.time_ns()
        for msg in frames:
            bus.send(msg)
        rec.join(TIMEOUT_S * 3)
        t_after = time.time_ns()
        assert not rec.is_alive() and result["code"] == 0
        assert sub.wait_for(lambda s: s.rate.received >= len(run), timeout_s=TIMEOUT_S)
        gone = lis.token_events(zenoh.SampleKind.DELETE, N_TOKENS)
        assert sorted(gone) == sorted(declared)
        assert lis.alive_tokens() == []
        summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        # zenoh sends declarations ahead of queued data (priorities): wait for every put
        samples = lis.samples(sum(t["sent"] for t in summary["ros2"]["topics"].values()))
    zid = summary["ros2"]["zid"]
    pubs = _check_tokens(declared, domain=0, zid=zid, ns="/", node="gyrotherm_bridge",
                         sensor="imu0")  # fmt: skip
    by_key: dict[str, list[tuple[bytes, bytes | None]]] = {}
    for key, payload, att in samples:
        by_key.setdefault(key, []).append((payload, att))
    keys = {t: f"0/gyrotherm/imu0/{t}/{DDS[ty]}/{STORE.hash_rihs01(ty)}"
            for t, ty in TOPIC_TYPES}
    assert set(by_key) == set(keys.values())
    assert {t: v["keyexpr"] for t, v in summary["ros2"]["topics"].items()} == {
        f"/gyrotherm/imu0/{t}": k for t, k in keys.items()}
    assert len(by_key[keys["imu"]]) == len(by_key[keys["imu_raw"]]) == len(rates) == len(run)
    assert {t: len(by_key[k]) for t, k in keys.items()} == {
        t.rsplit("/", 1)[1]: v["sent"] for t, v in summary["ros2"]["topics"].items()}
    for name, field in (("imu", "rate_dps"), ("imu_raw", "raw_rate_dps")):
        got = by_key[keys[name]]
        for (payload, _), sent in zip(got, rates, strict=True):
            m = STORE.deserialize_cdr(payload, IMU)
            ns = round(sent.sensor_time_s * 1e9)
            assert (m.header.stamp.sec, m.header.stamp.nanosec) == divmod(ns, 1_000_000_000)
            assert m.header.frame_id == "gyro_link"
            av = m.angular_velocity
            assert [av.x, av.y, av.z] == pytest.approx(
                [r * DEG for r in getattr(sent, field)], abs=1e-12, rel=0)
            assert m.orientation_covariance[0] == -1
        _check_attachments([a for _, a in got], _gid(pubs[f"%gyrotherm%imu0%{name}"]),
                           t_before, t_after)  # fmt: skip
    temps = by_key[keys["temperature"]]  # record may stop before the daemon's last state
    assert len(states) - 1 <= len(temps) <= len(states) and temps
    for (payload, _), s in zip(temps, states[:len(temps)], strict=True):
        t = STORE.deserialize_cdr(payload, TEMP)
        assert t.temperature == s.temperature_c and t.header.frame_id == "gyro_link"
    _check_attachments([a for _, a in temps], _gid(pubs["%gyrotherm%imu0%temperature"]),
                       None, t_after)  # fmt: skip


def _check_attachments(atts: list[bytes | None], gid: bytes, t_min: int | None,
                       t_max: int) -> None:  # fmt: skip
    decoded = [z_deserialize(tuple[Int64, Int64, bytes], zenoh.ZBytes(a)) for a in atts
               if a is not None]  # fmt: skip
    assert len(decoded) == len(atts) and all(a is not None and len(a) == 33 for a in atts)
    assert [seq for seq, _, _ in decoded] == list(range(1, len(atts) + 1))
    assert {g for _, _, g in decoded} == {gid}
    stamps = [ts for _, ts, _ in decoded]
    assert stamps == sorted(stamps) and stamps[-1] <= t_max
    if t_min is not None:
        assert stamps[0] >= t_min


def test_sigterm_undeclares_the_tokens() -> None:
    """No daemon: ``--ros2`` alone declares its node and publishers (domain 7, namespace
    /robot1), publishes nothing; SIGTERM removes the tokens, exit 1, JSON summary."""
    with dead_port() as port, listener(7) as lis, cli_process(
            "record", "--vehicle", "v", "--sensor", "s", "--connect", f"tcp/127.0.0.1:{port}",
            "--connect", lis.endpoint, "--ros2", "--ros-domain-id", "7", "--ros-namespace",
            "/robot1", "--ros-node-name", "br", "--json",
            "--calibration-timeout-s", "0.2") as proc:  # fmt: skip
        assert proc.stderr is not None
        line = proc.stderr.readline()  # printed once subscribed
        assert "ROS 2 node /robot1/br domain 7 (rmw_zenoh)" in line
        declared = lis.token_events(zenoh.SampleKind.PUT, N_TOKENS)
        assert lis.alive_tokens() == sorted(declared)
        stdout = stdout_after_sigterm(proc, TIMEOUT_S * 3)
        assert sorted(lis.token_events(zenoh.SampleKind.DELETE, N_TOKENS)) == sorted(declared)
        assert lis.alive_tokens() == []
    assert proc.returncode == 1
    summary = json.loads(stdout)
    assert summary["messages"] == {}
    ros = summary["ros2"]
    assert (ros["domain_id"], ros["namespace"], ros["node_name"]) == (7, "/robot1", "br")
    assert {t: v["sent"] for t, v in ros["topics"].items()} == {
        f"/robot1/gyrotherm/s/{t}": 0 for t, _ in TOPIC_TYPES}
    _check_tokens(declared, domain=7, zid=ros["zid"], ns="/robot1", node="br", sensor="s")
    assert lis.data.empty()


@pytest.mark.parametrize(("argv", "message"), [
    (["--mcap", "x.mcap", "--ros-domain-id", "3"], "--ros-domain-id only applies with --ros2"),
    (["--ros2", "--ros-namespace", "robot"], "not a ROS 2 namespace"),
    (["--ros2", "--ros-node-name", "my-node"], "not a ROS 2 node name"),
    (["--ros2", "--ros-domain-id", "300"], "out of 0..232"),
    ([], "--mcap FILE, --foxglove-port PORT and/or --ros2"),
])  # fmt: skip
def test_usage_errors(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert record_main(["--vehicle", "v", "--sensor", "s", *argv]) == 2
    assert message in capsys.readouterr().err


def test_a_sensor_name_ros_refuses(capsys: pytest.CaptureFixture[str]) -> None:
    assert record_main(["--vehicle", "v", "--sensor", "imu-0", "--ros2"]) == 2
    err = capsys.readouterr().err
    assert "--ros2: not a ROS 2 topic name: '/gyrotherm/imu-0/imu'" in err


def test_without_xxhash_the_extra_is_named(monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    monkeypatch.setitem(sys.modules, "xxhash", None)  # import xxhash → ImportError
    assert record_main(["--vehicle", "v", "--sensor", "s", "--ros2"]) == 2
    assert "pip install 'gyrotherm[ros2]'" in capsys.readouterr().err
