"""The daemon's Zenoh side: the pipeline sink backed by Zenoh publishers.

:class:`_ZenohSink` implements :class:`~gyrotherm.daemon._accounting.Sink`: it
declares the rate, state (both ``CongestionControl.BLOCK``) and health
publishers under :func:`gyrotherm._zenoh.keys` for the configured vehicle and
sensor; ``put_rate``/``put_state`` raise :class:`PublishError` on a zenoh error
and return whether a subscriber matched the message.

Zenoh connectivity: a put that no subscriber matches (router or link down,
nobody subscribed) is discarded by zenoh without an error. The sink follows
each publisher's matching status (zenoh matching listeners) and reports such
puts to the pipeline, which counts the frame as dropped ``no_subscriber``
(health ``drops``) while the message's ``seq`` is spent — the gap a subscriber
sees in ``seq`` is the one health reports. Matching changes and transports
(router, peers) opening and closing are logged; the reconnection itself is
zenoh's (``connect/retry`` in the Zenoh config), the daemon keeps running.

A slow or frozen subscriber (docs/operations.md, "A slow or frozen subscriber"):
rate and state use ``CongestionControl.BLOCK``, and the daemon sets zenoh's
``transport/link/tx/queue/congestion_control/block/wait_before_close`` to
``[zenoh] publish_block_max_s`` (:func:`bound_publishing`), so a put waits at most
that long for room on a full link; then zenoh gives the message up and closes
that link. The sink times each put (two monotonic clock reads) and reports a put
that took the whole bound, and every put after it until zenoh has closed the
link (a transport closing, or :data:`CONGESTION_HOLD_S`), as dropped
``congestion``: zenoh accepted those messages but they reach nobody on the
closing link. Messages already queued in zenoh or in the sockets when the link
closes are lost without the daemon knowing (counted ``published``); the TCP send
buffer is limited to :data:`TCP_SNDBUF_BYTES` (unless the Zenoh config file sets
it) so that a frozen subscriber fills it, and is noticed, within about a second.
"""

from __future__ import annotations

import json
import logging
import math
import time
from typing import Any

import zenoh

from gyrotherm._errors import ConfigError, PublishError
from gyrotherm._zenoh import keys, zenoh_error_text
from gyrotherm.daemon._config import DaemonConfig

log = logging.getLogger("gyrotherm.daemon")

#: Drop reason: the put blocked ``publish_block_max_s`` on a full link (a frozen or
#: too slow subscriber), or came while zenoh was closing such a link.
CONGESTION = "congestion"
#: Longest a congestion episode lasts without a transport closing, s (zenoh's default lease).
CONGESTION_HOLD_S = 10.0
#: TCP send buffer per zenoh link unless the Zenoh config sets one, bytes.
TCP_SNDBUF_BYTES = 131072
_WAIT_BEFORE_CLOSE = "transport/link/tx/queue/congestion_control/block/wait_before_close"
_SO_SNDBUF = "transport/link/tcp/so_sndbuf"
_mono = time.monotonic


def bound_publishing(zconf: zenoh.Config, publish_block_max_s: float) -> None:
    """Bound how long a BLOCK put may wait on a full link (zenoh then closes the link),
    and cap the TCP send buffer unless the config already sets one."""
    try:
        zconf.insert_json5(_WAIT_BEFORE_CLOSE, str(max(1, round(publish_block_max_s * 1e6))))
        if json.loads(zconf.get_json(_SO_SNDBUF)) is None:
            zconf.insert_json5(_SO_SNDBUF, str(TCP_SNDBUF_BYTES))
    except (zenoh.ZError, ValueError) as exc:
        raise ConfigError(f"zenoh config: cannot set {_WAIT_BEFORE_CLOSE} for "
                          f"publish_block_max_s = {publish_block_max_s!r}: "
                          f"{zenoh_error_text(exc)}") from exc


def _matching(publisher: zenoh.Publisher) -> bool:
    """The publisher's matching status now (zenoh 1.x returns a MatchingStatus)."""
    status: object = publisher.matching_status
    return bool(getattr(status, "matching", status))


class _ZenohSink:
    """Pipeline sink backed by Zenoh publishers.

    ``put_rate``/``put_state`` return whether a subscriber matched the message
    (False: nobody received it), or :data:`CONGESTION` (module docstring). The
    matched state is cached from matching listener callbacks (free on the hot
    path); while the cache says "no subscriber" each put asks the publisher
    again (≈3 µs), so a subscriber whose listener callback has not run yet is
    not counted as missing. A message lost
    on a link that dies before zenoh notices is not seen here.
    """

    def __init__(self, session: zenoh.Session, config: DaemonConfig) -> None:
        k = keys(config.vehicle, config.sensor)
        # BLOCK: a slow subscriber slows the daemon down and loses nothing; a put waits
        # at most publish_block_max_s (bound_publishing), then zenoh drops that link.
        cc = zenoh.CongestionControl.BLOCK
        self._session = session
        self._block_max_s = config.zenoh.publish_block_max_s
        self._congested_until = -math.inf  # monotonic s; a congestion episode lasts until then
        self.congestion_episodes = 0
        self.rate = session.declare_publisher(k.rate, congestion_control=cc)
        self.state = session.declare_publisher(k.state, congestion_control=cc)
        self.health = session.declare_publisher(k.health)
        self._put_rate = self.rate.put
        self._put_state = self.state.put
        self.rate_matched = False
        self.state_matched = False
        # Declared after the flags: zenoh calls back at once when already matched.
        self._listeners: list[Any] = [
            self.rate.declare_matching_listener(self._on_rate_matching),
            self.state.declare_matching_listener(self._on_state_matching),
            session.info.declare_transport_events_listener(self._on_transport),
        ]

    def _on_rate_matching(self, status: zenoh.MatchingStatus) -> None:
        self.rate_matched = status.matching
        if status.matching:
            log.info("zenoh: %s has a subscriber", self.rate.key_expr)
        else:
            log.info("zenoh: no subscriber matches %s: rate messages reach nobody "
                     "(counted in drops as 'no_subscriber')", self.rate.key_expr)

    def _on_state_matching(self, status: zenoh.MatchingStatus) -> None:
        self.state_matched = status.matching

    def _congestion(self, t0: float, what: str) -> str:
        if t0 >= self._congested_until:  # a new episode
            self.congestion_episodes += 1
            log.warning("zenoh: a %s put blocked %.2f s (publish_block_max_s): a subscriber's "
                        "link is full (frozen or too slow); zenoh closes that link, messages "
                        "until then are counted in drops as 'congestion'", what,
                        _mono() - t0)
            self._congested_until = t0 + CONGESTION_HOLD_S
        return CONGESTION

    def _on_transport(self, event: zenoh.TransportEvent) -> None:
        t = event.transport
        what = str(t.whatami).rsplit(".", 1)[-1].lower()
        if event.kind == zenoh.SampleKind.PUT:
            log.info("zenoh: connected to %s %s", what, t.zid)
        else:
            # the closed link ends a congestion episode; the matching listener may call
            # back late (seen: only once the frozen peer ran again), so ask now
            self._congested_until = -math.inf
            self.rate_matched = _matching(self.rate)
            self.state_matched = _matching(self.state)
            log.warning("zenoh: lost %s %s; zenoh reconnects to the configured "
                        "endpoints", what, t.zid)

    def transports(self) -> int:
        """Open zenoh transports (to routers and peers)."""
        return len(self._session.info.transports())

    def put_rate(self, payload: bytes) -> bool | str:
        t0 = _mono()
        try:
            self._put_rate(payload)
        except zenoh.ZError as exc:
            raise PublishError(f"rate: {zenoh_error_text(exc)}") from exc
        if t0 < self._congested_until or _mono() - t0 >= self._block_max_s:
            return self._congestion(t0, "rate")
        return self.rate_matched or _matching(self.rate)

    def put_state(self, payload: bytes) -> bool | str:
        t0 = _mono()
        try:
            self._put_state(payload)
        except zenoh.ZError as exc:
            raise PublishError(f"state: {zenoh_error_text(exc)}") from exc
        if t0 < self._congested_until or _mono() - t0 >= self._block_max_s:
            return self._congestion(t0, "state")
        return self.state_matched or _matching(self.state)

    def undeclare(self) -> None:
        for listener in self._listeners:
            listener.undeclare()
        for p in (self.rate, self.state, self.health):
            p.undeclare()
