"""``gyrotherm record``: simulated frames → daemon → Zenoh → record → MCAP, read back
with independent decoders (mcap-ros2-support; rosbags after converting to rosbag2)."""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.client._record import record_main
from gyrotherm.client._ros import imu_cdr, residual_variance_dps2, stamp, temperature_cdr
from gyrotherm.codecs import FrameEncoder, Run
from gyrotherm.codecs._wire import RateMessage, StateMessage
from gyrotherm.compensation import Calibration
from streamkit import run_frames

TIMEOUT_S = 20.0
DEG = math.pi / 180


class _Rec:
    def __init__(self, message: Any, decoded: Any) -> None:
        self.message, self.decoded_message = message, decoded


def _messages(path: Path) -> dict[str, list[tuple[Any, Any, _Rec]]]:
    """Every message by topic; ROS (cdr) ones decoded by mcap-ros2-support."""
    out: dict[str, list[tuple[Any, Any, _Rec]]] = {}
    ros = ["/gyrotherm/imu0/imu", "/gyrotherm/imu0/imu_raw", "/gyrotherm/imu0/temperature"]
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(topics=ros):
            out.setdefault(channel.topic, []).append((schema, channel, _Rec(message, decoded)))
        f.seek(0)
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.topic not in ros:
                out.setdefault(channel.topic, []).append((schema, channel, _Rec(message, None)))
    return out


def test_cdr_bytes_hand_computed() -> None:
    """Imu CDR laid out by hand: 4-byte CDR_LE header, stamp, frame_id, then float64s
    aligned to 8 from the end of the header."""
    data = imu_cdr(12.25, "g", (180.0, -90.0, 0.0), (1.0, 4.0, 0.0))
    assert data[:4] == b"\x00\x01\x00\x00"
    assert data[4:8] == (12).to_bytes(4, "little")
    assert data[8:12] == (250_000_000).to_bytes(4, "little")
    assert data[12:18] == b"\x02\x00\x00\x00g\x00"  # length 2 incl. NUL
    assert data[18:20] == b"\x00\x00"  # pad to offset 16 (from the header's end)
    assert len(data) == 4 + 16 + 8 * (4 + 9 + 3 + 9 + 3 + 9)
    assert stamp(-0.5) == (-1, 500_000_000)
    with pytest.raises(ValueError, match="int32"):
        stamp(2.0**31)
    assert len(temperature_cdr(1.0, "", 25.0, 0.01)) == 4 + 8 + 4 + 1 + 3 + 16


def test_residual_variance_pools_runs() -> None:
    cal = {"provenance": {"residuals": {"x:a": {"rms_dps": 0.1, "n": 100},
                                        "x:b": {"rms_dps": 0.2, "n": 300},
                                        "y:a": {"rms_dps": 0.3, "n": 10}}}}  # fmt: skip
    vx, vy, vz = residual_variance_dps2(cal)
    assert vx == pytest.approx((100 * 0.01 + 300 * 0.04) / 400)
    assert vy == pytest.approx(0.09) and vz == 0.0
    assert residual_variance_dps2(None) == (0.0, 0.0, 0.0)


def test_record_end_to_end(daemon: tuple[str, int], runs: list[Run], tmp_path: Path,
                           calibration: Calibration, capsys: pytest.CaptureFixture[str]) -> None:
    channel, port = daemon
    run = runs[1].slice(0, 300)
    frames = list(run_frames(run, FrameEncoder()))
    out = tmp_path / "rec.mcap"
    ready, result = threading.Event(), {}
    argv = ["--vehicle", "testcar", "--sensor", "imu0", "--connect", f"tcp/127.0.0.1:{port}",
            "--mcap", str(out), "--count", str(len(run)), "--frame-id", "gyro_link", "--json"]
    rec = threading.Thread(target=lambda: result.update(
        code=record_main(argv, on_ready=lambda _port: ready.set())))
    rates: list[RateMessage] = []
    states: list[StateMessage] = []
    with Subscriber("testcar", "imu0", connect=[f"tcp/127.0.0.1:{port}"],
                    on_rate=rates.append, on_state=states.append) as sub, \
            open_bus(interface="virtual", channel=channel) as bus:  # fmt: skip
        rec.start()
        assert ready.wait(TIMEOUT_S)
        assert sub.wait_for(lambda s: s.health.received >= 2, timeout_s=TIMEOUT_S)
        for msg in frames:
            bus.send(msg)
        rec.join(TIMEOUT_S * 3)
        assert not rec.is_alive() and result["code"] == 0
        assert sub.wait_for(lambda s: s.rate.received >= len(run), timeout_s=TIMEOUT_S)
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    var = residual_variance_dps2(calibration.to_dict())
    assert summary["angular_velocity_variance_dps2"] == pytest.approx(list(var))
    assert all(v > 0 for v in var)
    msgs = _messages(out)
    imu = msgs["/gyrotherm/imu0/imu"]
    raw = msgs["/gyrotherm/imu0/imu_raw"]
    assert len(imu) == len(raw) == len(rates) == len(run)
    for (schema, ch, m), (_, _, r), sent in zip(imu, raw, rates, strict=True):
        assert schema.name == "sensor_msgs/msg/Imu" and schema.encoding == "ros2msg"
        assert ch.message_encoding == "cdr"
        d, dr = m.decoded_message, r.decoded_message
        assert d.header.frame_id == "gyro_link"
        assert (d.header.stamp.sec, d.header.stamp.nanosec) == stamp(sent.sensor_time_s)
        av = d.angular_velocity
        assert (av.x, av.y, av.z) == pytest.approx([x * DEG for x in sent.rate_dps], rel=1e-15)
        rw = dr.angular_velocity
        assert (rw.x, rw.y, rw.z) == pytest.approx([x * DEG for x in sent.raw_rate_dps],
                                                   rel=1e-15)  # fmt: skip
        cov = d.angular_velocity_covariance
        assert [cov[0], cov[4], cov[8]] == pytest.approx([v * DEG**2 for v in var])
        assert d.orientation_covariance[0] == -1 and d.linear_acceleration_covariance[0] == -1
        assert m.message.log_time == round(sent.receive_time_s * 1e9)
    temps = msgs["/gyrotherm/imu0/temperature"]
    assert len(temps) == len(states) > 0
    for (_, _, m), s in zip(temps, states, strict=True):
        assert m.decoded_message.temperature == s.temperature_c
        assert m.decoded_message.variance == pytest.approx(s.temperature_std_c**2, rel=1e-15)
    st = [json.loads(m.message.data) for _, _, m in msgs["/gyrotherm/imu0/state"]]
    assert [x["delta_t_c"] for x in st] == [s.delta_t_c for s in states]
    assert msgs["/gyrotherm/imu0/state"][0][0].encoding == "jsonschema"
    assert len(msgs["/gyrotherm/imu0/health"]) >= 1
    _check_with_rosbags(out, tmp_path / "bag", rates)


def _check_with_rosbags(mcap_path: Path, bag: Path, rates: list[RateMessage]) -> None:
    """Convert the MCAP's ROS channels to a rosbag2 (rosbags' writer), read it back with
    rosbags' own CDR deserialiser and its built-in ROS 2 Humble types."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with mcap_path.open("rb") as f, Writer(bag, version=9) as w:
        conns: dict[str, Any] = {}
        for schema, ch, msg in make_reader(f).iter_messages():
            if ch.message_encoding != "cdr":
                continue
            if ch.topic not in conns:
                conns[ch.topic] = w.add_connection(ch.topic, schema.name, typestore=store)
            w.write(conns[ch.topic], msg.log_time, msg.data)
    with AnyReader([bag], default_typestore=store) as r:
        got = [r.deserialize(raw, c.msgtype) for c, _, raw in
               r.messages(connections=[c for c in r.connections
                                       if c.topic == "/gyrotherm/imu0/imu"])]  # fmt: skip
    assert len(got) == len(rates)
    for g, sent in zip(got, rates, strict=True):
        av = g.angular_velocity
        assert [av.x, av.y, av.z] == pytest.approx([x * DEG for x in sent.rate_dps], rel=1e-15)
        assert g.header.frame_id == "gyro_link"


def test_a_stamp_no_ros_time_holds_is_counted_not_written(tmp_path: Path) -> None:
    from gyrotherm.client._channels import Fanout, McapSink

    fan = Fanout([McapSink(str(tmp_path / "s.mcap"))], sensor="s")
    zero = (0.0, 0.0, 0.0)
    fan.on_rate(RateMessage(0, 2.0**40, 1.0, zero, zero, zero))
    fan.on_state(StateMessage(0, 2.0**40, 1.0, 20.0, 0.1, 0.0, 0.1, (0.0, 0.0, 0.0)))
    fan.close()
    assert fan.counts == {"unrepresentable_stamp": 2, "/gyrotherm/s/state": 1}
