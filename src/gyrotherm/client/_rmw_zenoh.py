"""ROS 2 over Zenoh as rmw_zenoh_cpp lays it out: key expressions, liveliness tokens,
the per-message attachment. Pure functions, no I/O, no ROS installation.

Checked against ros2/rmw_zenoh (rolling, changelog up to 0.10.4 of 2026-04-30; jazzy
≥ 0.2.4 has the same format) — docs/design.md @99a6a2bd,
rmw_zenoh_cpp/src/detail/liveliness_utils.cpp @3411fdec, attachment_helpers.cpp
@534747dc, rmw_publisher_data.cpp @3e19ec73, rmw_subscription_data.cpp @a72659a6 (a
sample without a well-formed attachment is dropped; the encoding is ignored),
rmw_node_data.cpp @3411fdec, qos.cpp @7efeee2b, type_support_common.cpp
(``_create_type_name``):

* **topic key** ``<domain_id>/<topic without leading/trailing '/'>/<type>/<hash>``,
  the type as DDS names it (``sensor_msgs::msg::dds_::Imu_``), the hash REP-2016's
  ``RIHS01_<64 hex>`` (``TopicInfo::TopicInfo``);
* **liveliness token** ``@ros2_lv/<domain_id>/<zid>/<node_id>/<entity_id>/<kind>/
  <enclave>/<namespace>/<node_name>[/<topic>/<type>/<hash>/<qos>]``, names
  "mangled" ('/' → '%', so namespace "/" is "%", topic "/a/b" is "%a%b"), kind
  ``NN`` (node: entity id = node id) or ``MP`` (publisher) (``Entity::Entity``);
* **QoS** ``qos_to_keyexpr``: ``rel:dur:hist,depth:dl_s,dl_ns:ls_s,ls_ns:liv,lease_s,
  lease_ns`` where every field equal to rmw_zenoh's default (KEEP_LAST 42, RELIABLE,
  VOLATILE, infinite deadline/lifespan/lease, AUTOMATIC) is left empty;
* **GID** of an entity: XXH3-128 (seed 0) of its token key expression, ``low64`` then
  ``high64``, each in host (little-endian) order (``Entity::Entity``);
* **attachment** of every ``put``: zenoh-ext serialisation of ``(int64 sequence
  number, int64 source timestamp in ns since the epoch, uint8[16] GID)`` = 8 bytes
  LE, 8 bytes LE, a LEB128 length (one byte, 16), 16 bytes: 33 bytes
  (``AttachmentData::serialize_to_zbytes``, design.md "Publishers"). Sequence
  numbers start at 1 per publisher; the timestamp is the wall clock at the put.

Older rmw_zenoh (jazzy 0.2.0-0.2.3, rolling < 0.6.0) keyed the attachment with the
strings "sequence_number", "source_timestamp", "source_gid": not produced here.
rmw_zenoh for humble has no type hashes (its keys differ): not targeted.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

#: REP-2016 type hashes (rosidl's RIHS01), as ``ros2 topic info -v`` prints them;
#: tests recompute them from the message definitions with rosbags' ``hash_rihs01``.
TYPE_HASHES = {
    "sensor_msgs/msg/Imu":
        "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    "sensor_msgs/msg/Temperature":
        "RIHS01_72514a14126ab9f8a9abec974c78e5610a367b59db5da355ff1fb982d5bad4b8",
    "geometry_msgs/msg/Vector3Stamped":
        "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a",
    "diagnostic_msgs/msg/DiagnosticArray":
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
}  # fmt: skip
ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER = "NN", "MP"
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE

# rmw/types.h enum values
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
AUTOMATIC = 1
INFINITE = (9_223_372_036, 854_775_807)  # RMW_DURATION_INFINITE (sec, nsec)

_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_NAMESPACE = re.compile(rf"/|(/{_TOKEN})+")
_NODE_NAME = re.compile(_TOKEN)
_TOPIC = re.compile(rf"(/{_TOKEN})+")
_TYPE = re.compile(rf"({_TOKEN})/msg/({_TOKEN})")


@dataclass(frozen=True, slots=True)
class Qos:
    """An rmw QoS profile as rmw_zenoh encodes it in a token (durations (sec, nsec))."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 42
    deadline: tuple[int, int] = INFINITE
    lifespan: tuple[int, int] = INFINITE
    liveliness: int = AUTOMATIC
    liveliness_lease: tuple[int, int] = INFINITE


#: rmw_zenoh's default profile (qos.cpp): every field of the token left empty.
DEFAULT_QOS = Qos()
#: What ``gyrotherm record --ros2`` declares: RELIABLE, VOLATILE, KEEP_LAST 10 (a
#: zenoh publisher with reliable transport and congestion control DROP, which is
#: what rmw_zenoh makes of RELIABLE + KEEP_LAST).
PUBLISHER_QOS = Qos(depth=10)


def qos_keyexpr(qos: Qos) -> str:
    """``qos_to_keyexpr``: e.g. ``"::,10:,:,:,,"`` for :data:`PUBLISHER_QOS`."""
    d = DEFAULT_QOS

    def f(value: int, default: int) -> str:
        return "" if value == default else str(value)

    return (f"{f(qos.reliability, d.reliability)}:{f(qos.durability, d.durability)}:"
            f"{f(qos.history, d.history)},{f(qos.depth, d.depth)}:"
            f"{f(qos.deadline[0], d.deadline[0])},{f(qos.deadline[1], d.deadline[1])}:"
            f"{f(qos.lifespan[0], d.lifespan[0])},{f(qos.lifespan[1], d.lifespan[1])}:"
            f"{f(qos.liveliness, d.liveliness)},"
            f"{f(qos.liveliness_lease[0], d.liveliness_lease[0])},"
            f"{f(qos.liveliness_lease[1], d.liveliness_lease[1])}")  # fmt: skip


def dds_type_name(ros_type: str) -> str:
    """``sensor_msgs/msg/Imu`` → ``sensor_msgs::msg::dds_::Imu_`` (``_create_type_name``)."""
    m = _TYPE.fullmatch(ros_type)
    if m is None:
        raise ValueError(f"not a ROS 2 message type name: {ros_type!r}")
    return f"{m[1]}::msg::dds_::{m[2]}_"


def type_hash(ros_type: str) -> str:
    """The RIHS01 hash of a type this module knows (:data:`TYPE_HASHES`)."""
    try:
        return TYPE_HASHES[ros_type]
    except KeyError:
        raise ValueError(f"no type hash known for {ros_type!r}") from None


def check_domain_id(domain_id: int) -> int:
    if not 0 <= domain_id <= 232:  # ROS_DOMAIN_ID's documented range
        raise ValueError(f"ROS domain id {domain_id} out of 0..232")
    return domain_id


def check_namespace(namespace: str) -> str:
    """A ROS 2 node namespace: ``/`` or ``/a/b`` (name tokens ``[A-Za-z_][A-Za-z0-9_]*``)."""
    if not _NAMESPACE.fullmatch(namespace):
        raise ValueError(f"not a ROS 2 namespace: {namespace!r} (e.g. '/' or '/robot1')")
    return namespace


def check_node_name(name: str) -> str:
    if not _NODE_NAME.fullmatch(name):
        raise ValueError(f"not a ROS 2 node name: {name!r} ([A-Za-z_][A-Za-z0-9_]*)")
    return name


def topic_name(namespace: str, relative: str) -> str:
    """Fully qualified topic: ``relative`` (``gyrotherm/imu0/imu``) under ``namespace``;
    ValueError unless every part is a ROS 2 name token (no '-', '.', leading digit)."""
    fq = check_namespace(namespace).rstrip("/") + "/" + relative.strip("/")
    if not _TOPIC.fullmatch(fq):
        raise ValueError(f"not a ROS 2 topic name: {fq!r} (name tokens are "
                         "[A-Za-z_][A-Za-z0-9_]*: rename the sensor or use another namespace)")
    return fq  # fmt: skip


def mangle(name: str) -> str:
    """``mangle_name``: every '/' → '%'."""
    return name.replace("/", "%")


def topic_keyexpr(domain_id: int, topic: str, ros_type: str) -> str:
    """The key expression the data goes on, e.g.
    ``0/gyrotherm/imu0/imu/sensor_msgs::msg::dds_::Imu_/RIHS01_7d9a…``."""
    return (f"{check_domain_id(domain_id)}/{topic.strip('/')}/{dds_type_name(ros_type)}/"
            f"{type_hash(ros_type)}")  # fmt: skip


def node_token(domain_id: int, zid: str, node_id: int, *, namespace: str, node_name: str,
               enclave: str = "/") -> str:  # fmt: skip
    """The node's (``NN``) liveliness token; its entity id is its node id."""
    return "/".join([ADMIN_SPACE, str(check_domain_id(domain_id)), zid, str(node_id),
                     str(node_id), NODE, mangle(enclave), mangle(check_namespace(namespace)),
                     mangle(check_node_name(node_name))])  # fmt: skip


def publisher_token(domain_id: int, zid: str, node_id: int, entity_id: int, *, namespace: str,
                    node_name: str, topic: str, ros_type: str, qos: Qos = PUBLISHER_QOS,
                    enclave: str = "/") -> str:  # fmt: skip
    """A publisher's (``MP``) liveliness token."""
    base = node_token(domain_id, zid, node_id, namespace=namespace, node_name=node_name,
                      enclave=enclave).split("/")  # fmt: skip
    base[4], base[5] = str(entity_id), PUBLISHER
    return "/".join([*base, mangle(topic), dds_type_name(ros_type), type_hash(ros_type),
                     qos_keyexpr(qos)])  # fmt: skip


def entity_gid(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity of ``token``: XXH3-128 of the key
    expression, low 64 bits then high 64 bits, little-endian (``Entity::Entity``)."""
    import xxhash  # lazy: only --ros2 needs it

    return int(xxhash.xxh3_128_intdigest(token.encode())).to_bytes(GID_SIZE, "little")


def attachment(sequence_number: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    """``AttachmentData::serialize_to_zbytes``: int64 LE, int64 LE, length 16, GID."""
    if len(gid) != GID_SIZE:
        raise ValueError(f"a GID has {GID_SIZE} bytes, not {len(gid)}")
    return struct.pack("<qqB", sequence_number, source_timestamp_ns, GID_SIZE) + gid

