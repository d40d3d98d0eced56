"""Bus adapters: frame sources and sinks shared by the daemon and the simulator.

The vehicle path (:mod:`gyrotherm.daemon`) opens its bus here; nothing in this
subpackage imports the simulator. ``socketcand`` is read by gyrotherm's own
client, :class:`SocketcandBus`; the reasons of the :class:`TransportItem` it
returns are :data:`TRANSPORT_MALFORMED`, :data:`TRANSPORT_ERROR` and
:data:`TRANSPORT_OTHER`.
"""

from gyrotherm.bus._bus import (
    INTERFACES,
    SOCKETCAND_PROBE_TIMEOUT_S,
    BusAdapter,
    FrameSink,
    FrameSource,
    TransportItem,
    open_bus,
)
from gyrotherm.bus._socketcand import HANDSHAKE_TIMEOUT_S, SocketcandBus
from gyrotherm.bus._socketcand_items import (
    TRANSPORT_ERROR,
    TRANSPORT_MALFORMED,
    TRANSPORT_OTHER,
)

__all__ = [
    "HANDSHAKE_TIMEOUT_S",
    "INTERFACES",
    "SOCKETCAND_PROBE_TIMEOUT_S",
    "TRANSPORT_ERROR",
    "TRANSPORT_MALFORMED",
    "TRANSPORT_OTHER",
    "BusAdapter",
    "FrameSink",
    "FrameSource",
    "SocketcandBus",
    "TransportItem",
    "open_bus",
]
