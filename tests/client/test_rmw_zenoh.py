"""The rmw_zenoh layout (gyrotherm.client._rmw_zenoh) against rmw_zenoh's own examples:
key expressions and liveliness tokens from ros2/rmw_zenoh docs/design.md and from a
real ``ros2 run demo_nodes_cpp talker`` printed in rmw_zenoh issue #643; type hashes
recomputed by rosbags from the message definitions; the attachment decoded by
zenoh-ext's own deserialiser; the GID's byte order from XXH3's published test vector."""

from __future__ import annotations

import pytest
from rosbags.typesys import Stores, get_typestore
from zenoh import ZBytes
from zenoh.ext import Int64, z_deserialize, z_serialize

from gyrotherm.client import _rmw_zenoh as rz

STRING = "std_msgs/msg/String"
LOG = "rcl_interfaces/msg/Log"
# docs/design.md (rmw_zenoh @99a6a2bd), "Topic and Service name mapping" / "Graph Cache"
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
# rmw_zenoh issue #643: what a talker under /robot1 declared (rosout publisher)
LOG_HASH = "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac"


@pytest.fixture()
def with_doc_types(monkeypatch: pytest.MonkeyPatch) -> None:
    """The design doc's and the issue's types, their hashes computed by rosbags."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for t in (STRING, LOG):
        monkeypatch.setitem(rz.TYPE_HASHES, t, store.hash_rihs01(t))


@pytest.mark.parametrize("store", [Stores.ROS2_JAZZY, Stores.ROS2_KILTED, Stores.LATEST])
def test_type_hashes_are_rosidls(store: Stores) -> None:
    ts = get_typestore(store)
    assert ts.hash_rihs01(STRING) == STRING_HASH  # rosbags' RIHS01 = rmw_zenoh's example
    assert ts.hash_rihs01(LOG) == LOG_HASH
    for name, h in rz.TYPE_HASHES.items():
        assert ts.hash_rihs01(name) == h


def test_topic_keyexprs_of_the_design_doc(with_doc_types: None) -> None:
    assert rz.topic_keyexpr(0, "/chatter", STRING) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}")
    assert rz.topic_keyexpr(0, rz.topic_name("/robot1", "chatter"), STRING) == (
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}")
    assert rz.topic_keyexpr(0, "/rosout", LOG) == (
        f"0/rosout/rcl_interfaces::msg::dds_::Log_/{LOG_HASH}")  # issue #643, "PUB KE"


def test_tokens_of_the_design_doc_and_issue_643(with_doc_types: None) -> None:
    assert rz.node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, namespace="/",
                         node_name="listener") == (
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener")  # fmt: skip
    assert rz.publisher_token(
        2, "8b20917502ee955ac4476e0266340d5c", 0, 10, namespace="/", node_name="talker",
        topic="/chatter", ros_type=STRING, qos=rz.Qos(depth=7)) == (
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
        f"std_msgs::msg::dds_::String_/{STRING_HASH}/::,7:,:,:,,")  # fmt: skip
    # rosout: TRANSIENT_LOCAL, KEEP_LAST 1000, lifespan 10 s (rclcpp's rosout QoS)
    rosout = rz.Qos(durability=rz.TRANSIENT_LOCAL, depth=1000, lifespan=(10, 0))
    assert rz.publisher_token(
        0, "999bf91283606d2068c7524e5badfa6c", 0, 1, namespace="/robot1", node_name="talker",
        topic="/rosout", ros_type=LOG, qos=rosout) == (
        "@ros2_lv/0/999bf91283606d2068c7524e5badfa6c/0/1/MP/%/%robot1/talker/%rosout/"
        f"rcl_interfaces::msg::dds_::Log_/{LOG_HASH}/:1:,1000:,:10,0:,,")  # fmt: skip
    assert rz.qos_keyexpr(rz.Qos(depth=1000)) == "::,1000:,:,:,,"  # parameter_events, #643


def test_qos_every_field() -> None:
    assert rz.qos_keyexpr(rz.DEFAULT_QOS) == "::,:,:,:,,"
    q = rz.Qos(reliability=rz.BEST_EFFORT, durability=rz.TRANSIENT_LOCAL, history=rz.KEEP_ALL,
               depth=5, deadline=(1, 2), lifespan=(3, 4), liveliness=3,
               liveliness_lease=(5, 6))  # fmt: skip
    assert rz.qos_keyexpr(q) == "2:1:2,5:1,2:3,4:3,5,6"
    assert rz.qos_keyexpr(rz.PUBLISHER_QOS) == "::,10:,:,:,,"


def test_imu_keys() -> None:
    topic = rz.topic_name("/", "gyrotherm/imu0/imu")
    assert topic == "/gyrotherm/imu0/imu"
    h = "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b"
    assert rz.topic_keyexpr(7, topic, "sensor_msgs/msg/Imu") == (
        f"7/gyrotherm/imu0/imu/sensor_msgs::msg::dds_::Imu_/{h}")
    assert rz.publisher_token(7, "ab" * 16, 0, 3, namespace="/car/a", node_name="br",
                              topic=rz.topic_name("/car/a", "gyrotherm/imu0/imu"),
                              ros_type="sensor_msgs/msg/Imu") == (
        f"@ros2_lv/7/{'ab' * 16}/0/3/MP/%/%car%a/br/%car%a%gyrotherm%imu0%imu/"
        f"sensor_msgs::msg::dds_::Imu_/{h}/::,10:,:,:,,")  # fmt: skip
    assert rz.dds_type_name("sensor_msgs/msg/Temperature") == "sensor_msgs::msg::dds_::Temperature_"


@pytest.mark.parametrize(("namespace", "relative"), [
    ("/", "gyrotherm/imu-0/imu"), ("/", "gyrotherm/0imu/imu"), ("/", "gyrotherm/imu.0/imu"),
    ("robot", "gyrotherm/imu0/imu"), ("/robot/", "gyrotherm/imu0/imu"), ("//", "a")])  # fmt: skip
def test_names_ros_refuses(namespace: str, relative: str) -> None:
    with pytest.raises(ValueError, match="ROS 2"):
        rz.topic_name(namespace, relative)


def test_bad_node_domain_type() -> None:
    with pytest.raises(ValueError, match="node name"):
        rz.node_token(0, "ab", 0, namespace="/", node_name="my-node")
    with pytest.raises(ValueError, match="domain"):
        rz.topic_keyexpr(233, "/a", "sensor_msgs/msg/Imu")
    with pytest.raises(ValueError, match="type hash"):
        rz.topic_keyexpr(0, "/a", "std_msgs/msg/Bool")
    with pytest.raises(ValueError, match="type name"):
        rz.dds_type_name("Imu")


def test_attachment_is_zenoh_ext_serialised() -> None:
    gid = bytes(range(100, 116))
    data = rz.attachment(5, -2, gid)
    # design.md "Publishers": 8 bytes LE, 8 bytes LE, 1 byte length (16), 16 bytes
    assert data == (b"\x05" + b"\x00" * 7 + b"\xfe" + b"\xff" * 7 + b"\x10" + gid)
    assert z_deserialize(tuple[Int64, Int64, bytes], ZBytes(data)) == (5, -2, gid)
    assert z_serialize((Int64(2**62), Int64(1_700_000_000_000_000_000), gid)).to_bytes() == (
        rz.attachment(2**62, 1_700_000_000_000_000_000, gid))
    with pytest.raises(ValueError, match="16"):
        rz.attachment(1, 1, b"\x00" * 12)


def test_gid_byte_order() -> None:
    """XXH3-128("") = high64 99aa06d3014798d8, low64 6001c324468d497f (xxHash's test
    vector); rmw_zenoh memcpy's low64 then high64 on a little-endian host."""
    low, high = 0x6001C324468D497F, 0x99AA06D3014798D8
    assert rz.entity_gid("") == low.to_bytes(8, "little") + high.to_bytes(8, "little")
    a = rz.entity_gid("@ros2_lv/0/ab/0/0/NN/%/%/n")
    assert len(a) == 16 and a != rz.entity_gid("@ros2_lv/0/ab/0/0/NN/%/%/m")
