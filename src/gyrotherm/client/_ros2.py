"""``gyrotherm record --ros2``: the record channels as a ROS 2 node on rmw_zenoh_cpp's
wire layout, so that ``ros2 topic echo`` (``RMW_IMPLEMENTATION=rmw_zenoh_cpp``, same
Zenoh router) sees them.

A :class:`~gyrotherm.client._channels.Sink`: the CDR channels (sensor_msgs/Imu
``imu``/``imu_raw``, sensor_msgs/Temperature ``temperature``/``delta_t``,
geometry_msgs/Vector3Stamped ``bias``, diagnostic_msgs/DiagnosticArray
``state``/``health``) are published; JSON channels (on request only) have no ROS 2
type and are skipped. On the given zenoh session it declares, in this order,

* the node's liveliness token (``NN``, node id 0, enclave "/"),
* for each channel a zenoh publisher on the topic key expression (reliable, congestion
  control DROP: rmw_zenoh's RELIABLE + KEEP_LAST) and the publisher's liveliness token
  (``MP``, entity ids 1, 2, … in channel order, QoS
  :data:`~gyrotherm.client._rmw_zenoh.PUBLISHER_QOS`),

and every ``put`` carries the rmw_zenoh attachment (sequence number from 1 per
publisher, the wall clock in ns at the put, the publisher's GID). :meth:`close`
undeclares the publisher tokens and publishers, then the node's token. Layout and the
rmw_zenoh sources it was checked against: :mod:`gyrotherm.client._rmw_zenoh`.

Topics: the channel's topic (``/gyrotherm/<sensor>/imu``) under the node namespace,
e.g. ``/robot1/gyrotherm/imu0/imu`` with ``namespace="/robot1"``.

**The session** (:func:`ros2_session_config`) is what an rmw_zenoh node has, so that a
router between record and the ROS 2 nodes works as it does between two nodes. rmw_zenoh's
``DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5`` (ros2/rmw_zenoh, commit 076f2e7) makes every
node a *peer* that connects to the router, listens on ``tcp/localhost:0`` and runs gossip
scouting towards the router; the router (``rmw_zenohd``) learns the peers by gossip and
either lets them connect to each other (``autoconnect``) or forwards between them
(``peers_failover_brokering``, which "only works if gossip discovery is enabled and peers
are configured with gossip target router"). A peer with gossip off and no listen
endpoint, record's earlier session, reaches the router but no node behind it. So with
``--ros2`` record's session is a peer with gossip on (multihop off, target the router,
autoconnect to routers and peers, ``greater-zid`` between peers, rmw_zenoh's values),
multicast off, listening on ``tcp/127.0.0.1:0`` (loopback, an ephemeral port), and
connecting to every ``--connect`` endpoint (the daemon, the router, or a router shared
by both).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh

from gyrotherm._zenoh import _insert, session_config
from gyrotherm.client import _rmw_zenoh as rz
from gyrotherm.client._channels import ChannelSpec

#: The channels published with ``--ros2``: every CDR channel, in this order (entity
#: ids 1, 2, …).
ROS2_TOPICS = ("imu", "imu_raw", "temperature", "delta_t", "bias", "state", "health")

#: rmw_zenoh's gossip settings for a node (DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5).
ROS2_GOSSIP: dict[str, Any] = {
    "enabled": True, "multihop": False,
    "target": {"router": ["router", "peer"], "peer": ["router"]},
    "autoconnect": {"router": [], "peer": ["router", "peer"]},
    "autoconnect_strategy": {"peer": {"to_router": "always", "to_peer": "greater-zid"}},
}


def ros2_session_config(connect: list[str] | tuple[str, ...]) -> zenoh.Config:
    """A session that behaves as an rmw_zenoh node's (module docstring): peer, listening
    on ``tcp/127.0.0.1:0``, gossip on, multicast off, connecting to ``connect``."""
    config = session_config(listen=["tcp/127.0.0.1:0"], connect=connect)
    _insert(config, "scouting/gossip", ROS2_GOSSIP)
    return config


@dataclass(slots=True)
class _Publication:
    topic: str
    keyexpr: str
    token: str
    gid: bytes
    publisher: Any
    liveliness: Any
    seq: int = 1
    sent: int = field(default=0)


def check_names(sensor: str, *, domain_id: int, namespace: str, node_name: str) -> list[str]:
    """The ROS 2 topics ``--ros2`` will publish; ValueError on a name ROS 2 refuses."""
    rz.check_domain_id(domain_id)
    rz.check_node_name(node_name)
    return [rz.topic_name(namespace, f"gyrotherm/{sensor}/{t}")
            for t in ROS2_TOPICS]  # fmt: skip


class RmwZenohSink:
    """The CDR channels published on ``session`` as rmw_zenoh_cpp lays them out."""

    def __init__(self, session: zenoh.Session, *, domain_id: int = 0, namespace: str = "/",
                 node_name: str = "gyrotherm_bridge",
                 clock_ns: Callable[[], int] = time.time_ns) -> None:  # fmt: skip
        self._session = session
        self.domain_id = rz.check_domain_id(domain_id)
        self.namespace = rz.check_namespace(namespace)
        self.node_name = rz.check_node_name(node_name)
        self.zid = str(session.zid())
        self._clock_ns = clock_ns
        self.node_token = rz.node_token(self.domain_id, self.zid, 0, namespace=namespace,
                                        node_name=node_name)  # fmt: skip
        self._node_liveliness: Any = session.liveliness().declare_token(self.node_token)
        self.publications: list[_Publication] = []

    def add_channel(self, spec: ChannelSpec) -> _Publication | None:
        if spec.message_encoding != "cdr":
            return None
        topic = rz.topic_name(self.namespace, spec.topic)
        keyexpr = rz.topic_keyexpr(self.domain_id, topic, spec.schema_name)
        token = rz.publisher_token(self.domain_id, self.zid, 0, len(self.publications) + 1,
                                   namespace=self.namespace, node_name=self.node_name,
                                   topic=topic, ros_type=spec.schema_name)  # fmt: skip
        publisher = self._session.declare_publisher(
            keyexpr, reliability=zenoh.Reliability.RELIABLE,
            congestion_control=zenoh.CongestionControl.DROP)  # fmt: skip
        pub = _Publication(topic, keyexpr, token, rz.entity_gid(token), publisher,
                           self._session.liveliness().declare_token(token))  # fmt: skip
        self.publications.append(pub)
        return pub

    def write(self, channel: _Publication | None, log_time_ns: int, data: bytes) -> None:
        if channel is None:
            return
        att = rz.attachment(channel.seq, self._clock_ns(), channel.gid)
        channel.publisher.put(data, attachment=att)
        channel.seq += 1
        channel.sent += 1

    def close(self) -> None:
        """Undeclare the publishers' tokens and publishers, then the node's token (once)."""
        if self._node_liveliness is None:
            return
        for pub in self.publications:
            pub.liveliness.undeclare()
            pub.publisher.undeclare()
        self._node_liveliness.undeclare()
        self._node_liveliness = None

    def summary(self) -> dict[str, Any]:
        """Domain, node, and per topic its key expression and messages put (``--json``)."""
        return {
            "domain_id": self.domain_id, "namespace": self.namespace,
            "node_name": self.node_name, "zid": self.zid,
            "topics": {p.topic: {"keyexpr": p.keyexpr, "sent": p.sent}
                       for p in self.publications},
        }  # fmt: skip
