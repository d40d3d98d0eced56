"""Bus adapters: frame sources and sinks shared by the daemon and the simulator.

The vehicle path (:mod:`gyrotherm.daemon`) opens its bus here; nothing in this
subpackage imports the simulator.
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

__all__ = [
    "INTERFACES",
    "SOCKETCAND_PROBE_TIMEOUT_S",
    "BusAdapter",
    "FrameSink",
    "FrameSource",
    "TransportItem",
    "open_bus",
]
