"""``gyrotherm record --foxglove-port``: daemon → Zenoh → record → Foxglove WebSocket,
read by an independent client (the ``websockets`` package speaking the Foxglove
WebSocket protocol by its v1 spec; CDR decoded by rosbags, not by the SDK).

Subprotocols: foxglove-sdk 0.30's server accepts ``foxglove.sdk.v1`` only, the new name
of ``foxglove.websocket.v1`` (the same messages: Foxglove's stated position, cited by
Lichtblick's PR #819 that added the new name). Current Foxglove (and Lichtblick from
its release with that PR) offer it; a client offering only ``foxglove.websocket.v1``
(older Lichtblick, roslibjs-foxglove) is refused with HTTP 400, as with
foxglove_bridge ≥ 3. Each is tested alone below."""

from __future__ import annotations

import json
import math
import queue
import struct
import threading
from typing import Any

import pytest
from websockets.sync.client import connect

from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.client._record import record_main
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.codecs._wire import RateMessage, StateMessage
from streamkit import run_frames

TIMEOUT_S = 20.0
DEG = math.pi / 180
SUBPROTOCOLS: list[Any] = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
TOPICS = {f"/gyrotherm/imu0/{t}" for t in ("imu", "imu_raw", "temperature", "delta_t", "bias",
                                           "state", "health")}


def _text(ws: Any) -> dict[str, Any]:
    msg = ws.recv(timeout=TIMEOUT_S)
    assert isinstance(msg, str), "expected a JSON text message"
    out: dict[str, Any] = json.loads(msg)
    return out


def test_foxglove_live_view(daemon: tuple[str, int], runs: list[Run]) -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    channel, port = daemon
    run = runs[0].slice(0, 120)
    frames = list(run_frames(run, FrameEncoder()))
    ports: queue.Queue[int | None] = queue.Queue()
    stop, result = threading.Event(), {}
    argv = ["--vehicle", "testcar", "--sensor", "imu0", "--connect", f"tcp/127.0.0.1:{port}",
            "--foxglove-port", "0", "-q"]
    rec = threading.Thread(target=lambda: result.update(
        code=record_main(argv, stop=stop, on_ready=ports.put)))
    rates: list[RateMessage] = []
    states: list[StateMessage] = []
    rec.start()
    try:
        ws_port = ports.get(timeout=TIMEOUT_S)
        assert ws_port
        # foxglove-sdk 0.30 accepts only "foxglove.sdk.v1", the successor of
        # "foxglove.websocket.v1" with the same serverInfo/advertise/subscribe and
        # message-data framing (checked below against the v1 spec): offer both.
        with connect(f"ws://127.0.0.1:{ws_port}", subprotocols=SUBPROTOCOLS,
                     open_timeout=TIMEOUT_S) as ws:  # fmt: skip
            assert ws.subprotocol in SUBPROTOCOLS
            assert _text(ws)["op"] == "serverInfo"
            channels: dict[int, dict[str, Any]] = {}
            while {c["topic"] for c in channels.values()} != TOPICS:
                m = _text(ws)
                if m["op"] == "advertise":
                    channels.update({c["id"]: c for c in m["channels"]})
            by_topic = {c["topic"]: c for c in channels.values()}
            imu_ch = by_topic["/gyrotherm/imu0/imu"]
            assert imu_ch["encoding"] == "cdr" and imu_ch["schemaName"] == "sensor_msgs/msg/Imu"
            assert imu_ch["schemaEncoding"] == "ros2msg"
            assert {c["encoding"] for c in channels.values()} == {"cdr"}
            assert by_topic["/gyrotherm/imu0/state"]["schemaName"] == \
                "diagnostic_msgs/msg/DiagnosticArray"
            subs = {i: c["topic"] for i, c in enumerate(channels.values())}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": i, "channelId": c["id"]} for i, c in enumerate(channels.values())]}))
            got: dict[str, list[tuple[int, bytes]]] = {t: [] for t in TOPICS}

            def receive_until(pred: Any) -> None:
                while not pred():
                    data = ws.recv(timeout=TIMEOUT_S)
                    if isinstance(data, str):
                        continue  # status etc.
                    op, sub_id, t_ns = struct.unpack_from("<BIQ", data)
                    assert op == 0x01
                    got[subs[sub_id]].append((t_ns, bytes(data[13:])))

            # the subscription is live once a health message (5 Hz) comes through it
            receive_until(lambda: got["/gyrotherm/imu0/health"])
            with Subscriber("testcar", "imu0", connect=[f"tcp/127.0.0.1:{port}"],
                            on_rate=rates.append, on_state=states.append) as sub, \
                    open_bus(interface="virtual", channel=channel) as bus:  # fmt: skip
                assert sub.wait_for(lambda s: s.health.received >= 2, timeout_s=TIMEOUT_S)
                for msg in frames:
                    bus.send(msg)
                assert sub.wait_for(lambda s: s.rate.received >= len(run), timeout_s=TIMEOUT_S)
                receive_until(lambda: all(len(got[f"/gyrotherm/imu0/{t}"]) >= n for t, n in (
                    ("imu", len(run)), ("imu_raw", len(run)), ("temperature", len(states)),
                    ("state", len(states)))))
    finally:
        stop.set()
        rec.join(TIMEOUT_S)
    assert result["code"] == 0
    imu = got["/gyrotherm/imu0/imu"]
    assert len(imu) == len(rates) == len(run)
    for (t_ns, data), sent in zip(imu, rates, strict=True):
        m = store.deserialize_cdr(data, "sensor_msgs/msg/Imu")
        av = m.angular_velocity
        assert [av.x, av.y, av.z] == pytest.approx([x * DEG for x in sent.rate_dps], rel=1e-15)
        assert m.header.frame_id == "imu0"
        assert t_ns == round(sent.receive_time_s * 1e9)
        # header stamps: the receive clock by default (ROS time)
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == divmod(t_ns, 1_000_000_000)
    raw = [store.deserialize_cdr(d, "sensor_msgs/msg/Imu") for _, d in
           got["/gyrotherm/imu0/imu_raw"]]  # fmt: skip
    assert [r.angular_velocity.x for r in raw] == pytest.approx(
        [s.raw_rate_dps[0] * DEG for s in rates], rel=1e-15)
    temps = [store.deserialize_cdr(d, "sensor_msgs/msg/Temperature").temperature
             for _, d in got["/gyrotherm/imu0/temperature"]]  # fmt: skip
    assert temps[:len(states)] == [s.temperature_c for s in states]
    dts = [store.deserialize_cdr(d, "sensor_msgs/msg/Temperature").temperature
           for _, d in got["/gyrotherm/imu0/delta_t"]][:len(states)]
    assert dts == [s.delta_t_c for s in states]
    st = [store.deserialize_cdr(d, "diagnostic_msgs/msg/DiagnosticArray").status[0]
          for _, d in got["/gyrotherm/imu0/state"]][:len(states)]
    assert [dict((kv.key, kv.value) for kv in x.values)["flags"] for x in st] == [
        f"0x{int(s.flags):x}" for s in states]


@pytest.mark.parametrize(("offered", "accepted"), [
    (["foxglove.sdk.v1"], True), (["foxglove.websocket.v1"], False),
    (["foxglove.websocket.v1", "foxglove.sdk.v1"], True)])
def test_each_subprotocol_alone(offered: list[str], accepted: bool) -> None:
    """What a client offering each subprotocol gets from the live server."""
    from websockets.exceptions import InvalidStatus

    from gyrotherm.client._foxglove import FoxgloveSink

    sink = FoxgloveSink(port=0)
    try:
        url = f"ws://127.0.0.1:{sink.port}"
        if accepted:
            with connect(url, subprotocols=offered, open_timeout=TIMEOUT_S) as ws:
                assert ws.subprotocol == "foxglove.sdk.v1"
                assert _text(ws)["op"] == "serverInfo"
        else:
            with pytest.raises(InvalidStatus) as info:
                connect(url, subprotocols=offered, open_timeout=TIMEOUT_S)
            assert info.value.response.status_code == 400
    finally:
        sink.close()
