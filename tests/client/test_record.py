"""``gyrotherm record``: simulated frames → daemon → Zenoh → record → MCAP, read back
with independent decoders, the way ROS 2 users' tools open it:

* mcap-ros2-support's ``read_ros2_messages`` with **no topic filter** (it raises
  ``DecoderNotFoundError`` on any non-CDR channel);
* rosbags' ``AnyReader`` on the **bare file** (it raised ``KeyError: 'jsonschema'`` on
  the JSON channels);
* the file inside a rosbag2 directory with a ``metadata.yaml`` in rosbag2's layout
  (version 9, storage ``mcap``), read by rosbags' rosbag2 ``Reader``, which is what
  ``ros2 bag play imu0_bag`` opens; every topic with one serialization format, which
  rosbag2's ``SequentialReader::check_topics_serialization_formats`` requires
  (ros2/rosbag2 ``rosbag2_cpp/src/rosbag2_cpp/readers/sequential_reader.cpp``), and
  each channel's ``offered_qos_profiles`` parsing as rosbag2's MCAP storage writes it.
"""

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
    """Every message by topic, decoded by mcap-ros2-support with no topic filter."""
    out: dict[str, list[tuple[Any, Any, _Rec]]] = {}
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            out.setdefault(channel.topic, []).append((schema, channel, _Rec(message, decoded)))
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
            "--mcap", str(out), "--count", str(len(run)), "--frame-id", "gyro_link", "--json",
            "--stamp", "sensor"]
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
    assert {ch.message_encoding for t in msgs.values() for _, ch, _ in t} == {"cdr"}
    imu = msgs["/gyrotherm/imu0/imu"]
    raw = msgs["/gyrotherm/imu0/imu_raw"]
    assert len(imu) == len(raw) == len(rates) == len(run)
    for (schema, _ch, m), (_, _, r), sent in zip(imu, raw, rates, strict=True):
        assert schema.name == "sensor_msgs/msg/Imu" and schema.encoding == "ros2msg"
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
        # the raw rate's error includes the bias removed from it: var + b², per axis
        rcov = dr.angular_velocity_covariance
        assert [rcov[0], rcov[4], rcov[8]] == pytest.approx(
            [(v + b * b) * DEG**2 for v, b in zip(var, sent.bias_dps, strict=True)])
        assert min(rcov[0] - cov[0], rcov[4] - cov[4], rcov[8] - cov[8]) > 0
        assert d.orientation_covariance[0] == -1 and d.linear_acceleration_covariance[0] == -1
        assert m.message.log_time == round(sent.receive_time_s * 1e9)
    temps = msgs["/gyrotherm/imu0/temperature"]
    assert len(temps) == len(states) > 0
    for (_, _, m), s in zip(temps, states, strict=True):
        assert m.decoded_message.temperature == s.temperature_c
        assert m.decoded_message.variance == pytest.approx(s.temperature_std_c**2, rel=1e-15)
    dts = [m.decoded_message for _, _, m in msgs["/gyrotherm/imu0/delta_t"]]
    assert [d.temperature for d in dts] == [s.delta_t_c for s in states]
    bias = [m.decoded_message.vector for _, _, m in msgs["/gyrotherm/imu0/bias"]]
    assert [c for b in bias for c in (b.x, b.y, b.z)] == pytest.approx(
        [v * DEG for s in states for v in s.bias_dps], rel=1e-15)
    st = [m.decoded_message.status[0] for _, _, m in msgs["/gyrotherm/imu0/state"]]
    assert [x.name for x in st] == ["gyrotherm/imu0/state"] * len(states)
    for x, s in zip(st, states, strict=True):
        kv = {v.key: v.value for v in x.values}
        assert float(kv["delta_t_c"]) == s.delta_t_c and kv["flags"] == f"0x{int(s.flags):x}"
        assert x.level == (0 if not s.flags else 1 if not s.flags & 0x2f08 else 2)
    health = [m.decoded_message.status[0] for _, _, m in msgs["/gyrotherm/imu0/health"]]
    assert health and all(h.hardware_id == "imu0" for h in health)
    assert "frames_received" in {v.key for v in health[-1].values}
    _check_with_rosbags(out, tmp_path / "bag", rates)


def test_json_channels_only_on_request(tmp_path: Path) -> None:
    from gyrotherm.client._channels import Fanout, McapSink

    zero = (0.0, 0.0, 0.0)
    for json_channels in (False, True):
        path = tmp_path / f"j{json_channels}.mcap"
        fan = Fanout([McapSink(str(path))], sensor="s", json_channels=json_channels)
        fan.on_state(StateMessage(0, 5.0, 6.0, 20.0, 0.1, 0.5, 0.1, zero))
        fan.close()
        with path.open("rb") as f:
            encodings = {ch.topic: ch.message_encoding for ch in
                         make_reader(f).get_summary().channels.values()}  # type: ignore[union-attr]
        assert ("/gyrotherm/s/state_json" in encodings) is json_channels
        assert set(encodings.values()) == ({"cdr", "json"} if json_channels else {"cdr"})


def _yaml_load(text: str) -> Any:
    from ruamel.yaml import YAML  # rosbags' own YAML library

    return YAML(typ="safe").load(text)


def _yaml_dump(data: Any, path: Path) -> None:
    from ruamel.yaml import YAML

    with path.open("w") as f:
        YAML(typ="safe").dump(data, f)


def _check_with_rosbags(mcap_path: Path, bag: Path, rates: list[RateMessage]) -> None:
    """The bare file with rosbags' AnyReader, then the same file in a rosbag2 directory
    (metadata.yaml in rosbag2's version-9 layout, storage mcap) with rosbags' rosbag2
    Reader: every message of every topic deserialises with the Humble typestore."""
    import shutil

    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with mcap_path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    counts = {ch.topic: summary.statistics.channel_message_counts.get(i, 0)
              for i, ch in summary.channels.items()}
    for ch in summary.channels.values():  # rosbag2's MCAP channel metadata
        qos = _yaml_load(ch.metadata["offered_qos_profiles"])
        assert qos == [{"history": 1, "depth": 10, "reliability": 1, "durability": 2,
                        "deadline": {"sec": 0, "nsec": 0}, "lifespan": {"sec": 0, "nsec": 0},
                        "liveliness": 1, "liveliness_lease_duration": {"sec": 0, "nsec": 0},
                        "avoid_ros_namespace_conventions": False}]
        schema = summary.schemas[ch.schema_id]
        assert ch.metadata["topic_type_hash"] == store.hash_rihs01(schema.name)
    with AnyReader([mcap_path], default_typestore=store) as r:
        seen = {c.topic: 0 for c in r.connections}
        got = []
        for c, _, raw in r.messages():
            m = r.deserialize(raw, c.msgtype)
            seen[c.topic] += 1
            if c.topic == "/gyrotherm/imu0/imu":
                got.append(m)
    assert seen == counts
    assert len(got) == len(rates)
    for g, sent in zip(got, rates, strict=True):
        av = g.angular_velocity
        assert [av.x, av.y, av.z] == pytest.approx([x * DEG for x in sent.rate_dps], rel=1e-15)
        assert g.header.frame_id == "gyro_link"
    # rosbag2's directory layout around the same file (what `ros2 bag play DIR` opens)
    bag.mkdir()
    shutil.copy(mcap_path, bag / "imu0_0.mcap")
    start = summary.statistics.message_start_time
    topics = [{"topic_metadata": {
        "name": ch.topic, "type": summary.schemas[ch.schema_id].name,
        "serialization_format": ch.message_encoding,
        "offered_qos_profiles": ch.metadata["offered_qos_profiles"],
        "type_description_hash": ch.metadata["topic_type_hash"]},
        "message_count": counts[ch.topic]} for ch in summary.channels.values()]
    meta = {"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": ["imu0_0.mcap"],
        "duration": {"nanoseconds": summary.statistics.message_end_time - start},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": summary.statistics.message_count,
        "topics_with_message_count": topics, "compression_format": "",
        "compression_mode": "", "files": [{"path": "imu0_0.mcap", "starting_time": {
            "nanoseconds_since_epoch": start}, "duration": {
            "nanoseconds": summary.statistics.message_end_time - start},
            "message_count": summary.statistics.message_count}],
        "custom_data": {}, "ros_distro": "humble"}}
    _yaml_dump(meta, bag / "metadata.yaml")
    with Reader(bag) as r2:
        assert {c.topic: c.msgcount for c in r2.connections} == counts
        assert {c.msgtype for c in r2.connections} >= {
            "sensor_msgs/msg/Imu", "diagnostic_msgs/msg/DiagnosticArray"}
        n = sum(1 for c, _, raw in r2.messages() if store.deserialize_cdr(raw, c.msgtype))
    assert n == sum(counts.values())


def test_a_stamp_no_ros_time_holds_is_counted_not_written(tmp_path: Path) -> None:
    from gyrotherm.client._channels import Fanout, McapSink

    fan = Fanout([McapSink(str(tmp_path / "s.mcap"))], sensor="s", stamp="sensor")
    zero = (0.0, 0.0, 0.0)
    fan.on_rate(RateMessage(0, 2.0**40, 1.0, zero, zero, zero))
    fan.on_state(StateMessage(0, 2.0**40, 1.0, 20.0, 0.1, 0.0, 0.1, (0.0, 0.0, 0.0)))
    fan.close()
    assert fan.counts == {"unrepresentable_stamp": 2}
    fan = Fanout([McapSink(str(tmp_path / "s2.mcap"))], sensor="s", json_channels=True,
                 stamp="sensor")
    fan.on_state(StateMessage(0, 2.0**40, 1.0, 20.0, 0.1, 0.0, 0.1, (0.0, 0.0, 0.0)))
    fan.close()  # the JSON state has no such limit
    assert fan.counts == {"unrepresentable_stamp": 1, "/gyrotherm/s/state_json": 1}
