"""Frame accounting of the pipeline: drop reasons, the sink protocol, the counters.

Every frame handed to :meth:`gyrotherm.daemon.Pipeline.process` is either published (a rate
frame as a ``rate`` message, a temperature frame as a ``state`` message) or
dropped with a reason, so ``frames_received == frames_published +
sum(drops.values())`` at all times. Reasons: the decoder's reject reasons;
``publish_error`` (the sink raised: the message never left and the next one
reuses its ``seq``); ``no_subscriber`` (the sink sent the message but no
subscriber matched it — router or link down, or nobody subscribed — so nobody
received it; its ``seq`` is spent, which is how a subscriber that comes back
sees the gap); ``bad_timestamp`` (a time stamp outside its stream's window,
see :mod:`gyrotherm.daemon._pipeline`, *Time stamps*); the
``reason`` of a :class:`gyrotherm.bus.TransportItem` (something read from the
link that is not a frame, e.g. ``transport_malformed``);
``internal_error`` (an unexpected exception while processing the frame: logged,
and the stream goes on); ``congestion`` (a drop reason the sink returned: the
message was handed to Zenoh, ``seq`` spent, but a full link to a frozen or too
slow subscriber gave it up — see :mod:`gyrotherm.daemon._sink`).
``frames_published`` counts what Zenoh accepted; messages a link loses after that
(a link that dies with messages in flight) are seen only as ``seq`` gaps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

#: Drop reason: the sink raised :class:`PublishError`; the message never left.
PUBLISH_ERROR = "publish_error"
#: Drop reason: the message was sent (``seq`` spent) but no subscriber matched it.
NO_SUBSCRIBER = "no_subscriber"
#: Drop reason: an unexpected exception while processing the frame (logged).
INTERNAL_ERROR = "internal_error"


class Sink(Protocol):
    """Where payloads go; each call may raise :class:`PublishError` (the payload
    never left: dropped as ``publish_error``, ``seq`` reused).

    Otherwise the payload left (its ``seq`` is spent) and a call returns ``True``
    or ``None`` when it was published, ``False`` when no subscriber matched it
    (nobody received it: dropped as ``no_subscriber``), or a drop-reason string
    when it was handed over but given up for that reason (``congestion``).
    """

    def put_rate(self, payload: bytes) -> bool | str | None: ...

    def put_state(self, payload: bytes) -> bool | str | None: ...


@dataclass(frozen=True)
class Counters:
    """Frame accounting snapshot. ``counter_jumps``: CAN counter jumps the decoder saw
    in both mapped messages (rate and temperature), delivered or rejected."""

    frames_received: int
    frames_published: int
    rate_published: int
    state_published: int
    drops: dict[str, int]
    counter_jumps: int
