"""The daemon's Zenoh side: the pipeline sink backed by Zenoh publishers.

:class:`_ZenohSink` implements :class:`~gyrotherm.daemon._pipeline.Sink`: it
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
"""

from __future__ import annotations

import logging
from typing import Any

import zenoh

from gyrotherm._errors import PublishError
from gyrotherm._zenoh import keys
from gyrotherm.daemon._config import DaemonConfig

log = logging.getLogger("gyrotherm.daemon")


def _matching(publisher: zenoh.Publisher) -> bool:
    """The publisher's matching status now (zenoh 1.x returns a MatchingStatus)."""
    status: object = publisher.matching_status
    return bool(getattr(status, "matching", status))


class _ZenohSink:
    """Pipeline sink backed by Zenoh publishers.

    ``put_rate``/``put_state`` return whether a subscriber matched the message
    (False: nobody received it). The matched state is cached from matching
    listener callbacks (free on the hot path); while the cache says "no
    subscriber" each put asks the publisher again (≈3 µs), so a subscriber whose
    listener callback has not run yet is not counted as missing. A message lost
    on a link that dies before zenoh notices is not seen here.
    """

    def __init__(self, session: zenoh.Session, config: DaemonConfig) -> None:
        k = keys(config.vehicle, config.sensor)
        # BLOCK: a message zenoh accepts is never discarded for a full queue, so
        # "published" means sent; a stuck network stalls the loop and the watchdog fires.
        cc = zenoh.CongestionControl.BLOCK
        self._session = session
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

    def _on_transport(self, event: zenoh.TransportEvent) -> None:
        t = event.transport
        what = str(t.whatami).rsplit(".", 1)[-1].lower()
        if event.kind == zenoh.SampleKind.PUT:
            log.info("zenoh: connected to %s %s", what, t.zid)
        else:
            log.warning("zenoh: lost %s %s; zenoh reconnects to the configured "
                        "endpoints", what, t.zid)

    def transports(self) -> int:
        """Open zenoh transports (to routers and peers)."""
        return len(self._session.info.transports())

    def put_rate(self, payload: bytes) -> bool:
        try:
            self._put_rate(payload)
        except zenoh.ZError as exc:
            raise PublishError(f"rate: {exc}") from exc
        return self.rate_matched or _matching(self.rate)

    def put_state(self, payload: bytes) -> bool:
        try:
            self._put_state(payload)
        except zenoh.ZError as exc:
            raise PublishError(f"state: {exc}") from exc
        return self.state_matched or _matching(self.state)

    def undeclare(self) -> None:
        for listener in self._listeners:
            listener.undeclare()
        for p in (self.rate, self.state, self.health):
            p.undeclare()
