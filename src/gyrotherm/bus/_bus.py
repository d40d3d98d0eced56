"""Frame sources and sinks: the one interface real CAN buses and the simulator share.

This subpackage is the vehicle path's only door to a bus: the daemon and the
simulator both use it, and it imports nothing of :mod:`gyrotherm.sim`.

Contract (python-can's :class:`can.BusABC` shape, with units in the names):

* :class:`FrameSink` ``.send(msg, timeout_s=None)`` hands one classic CAN frame
  (:class:`can.Message`) to the bus; ``timeout_s`` bounds how long it may block
  (``None``: the implementation's default).
* :class:`FrameSource` ``.recv(timeout_s=None)`` returns the next frame, or
  ``None`` once ``timeout_s`` seconds passed without one (``None`` waits
  forever, ``0`` polls). Iterating a source yields frames until it is shut down.
  A source that reads a byte stream (socketcand) may also return a
  :class:`TransportItem`: something that arrived on the link but is not a frame
  (malformed text, a server's error line). Consumers count it (the daemon drops
  it by its ``reason``) and go on; it is never raised.
* Both have an idempotent ``shutdown()``, an ``is_shutdown`` property, and are
  context managers that shut down on exit.

:class:`BusAdapter` makes any python-can bus (``virtual``, ``socketcan`` on a
vehicle) both a source and a sink; :class:`~gyrotherm.bus._socketcand.SocketcandBus`
(gyrotherm's own socketcand client) is both too, so code written against these
interfaces runs unchanged on a real bus or on the simulator's
:class:`~gyrotherm.sim._socketcand.SocketcandServer`. :func:`open_bus` opens the
buses gyrotherm supports and rejects bad options with
:class:`gyrotherm.ConfigError` naming the field, the limit and the value.
"""

from __future__ import annotations

import errno
import socket
import threading
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any, Self

import can

from gyrotherm._errors import ConfigError

if TYPE_CHECKING:
    from gyrotherm.bus._socketcand import SocketcandBus

INTERFACES = ("virtual", "socketcan", "socketcand")
"""The python-can interfaces :func:`open_bus` accepts."""

_ITER_POLL_S = 0.1  # how often an iterating consumer re-checks ``is_shutdown``


@dataclass(frozen=True, slots=True)
class TransportItem:
    """An item read from a bus link that is not a CAN frame.

    ``reason`` is a drop reason (a short snake_case word such as
    ``transport_malformed``) that the daemon counts; ``detail`` says what was
    wrong and quotes (a bounded part of) the offending bytes, for a rate-limited log.
    """

    reason: str
    detail: str


class _Endpoint(ABC):
    """Common lifetime of sources and sinks: idempotent shutdown, context manager."""

    @property
    @abstractmethod
    def is_shutdown(self) -> bool:
        """True once :meth:`shutdown` has been called."""

    @abstractmethod
    def shutdown(self) -> None:
        """Release every resource; calling it again does nothing."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.shutdown()


class FrameSink(_Endpoint):
    """Something classic CAN frames can be sent to."""

    @abstractmethod
    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        """Send one frame, blocking at most ``timeout_s`` seconds (``None``: default)."""


class FrameSource(_Endpoint):
    """Something classic CAN frames can be received from."""

    @abstractmethod
    def recv(self, timeout_s: float | None = None) -> can.Message | TransportItem | None:
        """Next frame (or non-frame :class:`TransportItem`), or ``None`` after
        ``timeout_s`` seconds (``None``: wait forever)."""

    @property
    def link_lost(self) -> bool:
        """True once the source knows its link is gone (a stream peer closed the
        connection); the owner should shut it down and reopen. Buses without a
        link to lose (virtual, SocketCAN) always say False."""
        return False

    def __iter__(self) -> Iterator[can.Message]:
        """Yield frames as they arrive until the source is shut down (transport
        items are skipped)."""
        while True:
            msg = self.recv(timeout_s=_ITER_POLL_S)
            if isinstance(msg, can.Message):
                yield msg
            elif self.is_shutdown:
                return


class BusAdapter(FrameSource, FrameSink):
    """A python-can bus seen as a :class:`FrameSource` and a :class:`FrameSink`.

    The adapter owns the bus: :meth:`shutdown` shuts it down (once). python-can
    errors (:class:`can.CanError`) propagate unchanged from ``send``/``recv``.
    """

    def __init__(self, bus: can.BusABC) -> None:
        self._bus = bus
        self._lock = threading.Lock()
        self._closed = False

    @property
    def bus(self) -> can.BusABC:
        """The wrapped python-can bus."""
        return self._bus

    @property
    def is_shutdown(self) -> bool:
        return self._closed

    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        self._bus.send(msg, timeout=timeout_s)

    def recv(self, timeout_s: float | None = None) -> can.Message | None:
        if self._closed:
            return None
        msg: can.Message | None = self._bus.recv(timeout=timeout_s)
        return msg

    def shutdown(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._bus.shutdown()

    def __repr__(self) -> str:
        return f"BusAdapter({self._bus.channel_info!r})"


def _check_options(
    interface: str,
    channel: str,
    bitrate: int | None,
    host: str | None,
    port: int | None,
    receive_own_messages: bool,
) -> None:
    if interface not in INTERFACES:
        raise ConfigError(f"interface: must be one of {', '.join(INTERFACES)}, got {interface!r}")
    if not isinstance(channel, str) or not channel or len(channel) > 16 or " " in channel:
        raise ConfigError(
            f"channel: must be a CAN interface name of 1 to 16 characters without spaces,"
            f" got {channel!r}"
        )
    if bitrate is not None and (
        isinstance(bitrate, bool) or not isinstance(bitrate, int) or not 0 < bitrate <= 1_000_000
    ):
        raise ConfigError(f"bitrate: must be an integer in 1..1000000 bit/s, got {bitrate!r}")
    if interface == "socketcand":
        if not isinstance(host, str) or not host:
            raise ConfigError(f"host: interface 'socketcand' needs a host name, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 < port <= 65535:
            raise ConfigError(
                f"port: interface 'socketcand' needs a port in 1..65535, got {port!r}"
            )
        if receive_own_messages:
            raise ConfigError(
                "receive_own_messages: not supported by interface 'socketcand', got True"
            )
    else:
        if host is not None:
            raise ConfigError(f"host: only interface 'socketcand' takes a host, got {host!r}")
        if port is not None:
            raise ConfigError(f"port: only interface 'socketcand' takes a port, got {port!r}")


def _socketcan_error(channel: str, exc: OSError) -> ConfigError:
    if exc.errno == errno.EAFNOSUPPORT:
        why = (
            "SocketCAN is unavailable on this machine: the kernel refuses AF_CAN sockets"
            " (no CAN support, e.g. inside a container)"
        )
    elif exc.errno == errno.ENODEV:
        why = f"no CAN network interface named {channel!r} (see `ip link`)"
    else:
        why = "SocketCAN could not open the interface"
    return ConfigError(
        f"interface 'socketcan', channel {channel!r}: {why} ({exc});"
        " use interface 'socketcand' (e.g. the gyrotherm simulator) or 'virtual' instead"
    )


SOCKETCAND_PROBE_TIMEOUT_S = 1.0
"""Longest wait for a socketcand server's TCP port before giving up, s."""


def _probe_socketcand(host: str, port: int, channel: str) -> None:
    """Fail fast (ConfigError) when nothing accepts TCP connections at host:port."""
    try:
        socket.create_connection((host, port), timeout=SOCKETCAND_PROBE_TIMEOUT_S).close()
    except OSError as exc:
        raise ConfigError(
            f"interface 'socketcand', channel {channel!r} at {host}:{port}: cannot open the "
            f"bus (no socketcand server within {SOCKETCAND_PROBE_TIMEOUT_S:g} s: {exc})"
        ) from exc


def open_bus(
    *,
    interface: str,
    channel: str,
    bitrate: int | None = None,
    host: str | None = None,
    port: int | None = None,
    receive_own_messages: bool = False,
    handshake_timeout_s: float | None = None,
) -> BusAdapter | SocketcandBus:
    """Open a bus as a :class:`FrameSource` and :class:`FrameSink`.

    * ``virtual``: python-can's in-process bus; ``channel`` names it. Frames keep
      the sender's timestamps (``preserve_timestamps``).
    * ``socketcan``: a Linux CAN interface (``can0`` on a vehicle); ``bitrate`` is
      informative only (set it with ``ip link``).
    * ``socketcand``: a socketcand server at ``host``:``port`` serving ``channel``,
      read by gyrotherm's own client :class:`~gyrotherm.bus._socketcand.SocketcandBus`
      (never raises on what the peer sends; malformed items come back as
      :class:`TransportItem`). The TCP port is probed first (at most
      :data:`SOCKETCAND_PROBE_TIMEOUT_S`), then connect and handshake take at most
      ``handshake_timeout_s`` (default
      :data:`~gyrotherm.bus._socketcand.HANDSHAKE_TIMEOUT_S`); a peer that accepts
      and then does not speak the protocol raises :class:`gyrotherm.BusError`.

    The python-can buses (``virtual``, ``socketcan``) come wrapped in a
    :class:`BusAdapter`; their configuration files and ``CAN_*`` environment
    variables are ignored: only these arguments count. Raises
    :class:`gyrotherm.ConfigError` naming the field for a bad option, and
    (chained from the cause) when the bus cannot be opened.
    """
    _check_options(interface, channel, bitrate, host, port, receive_own_messages)
    if handshake_timeout_s is not None and interface != "socketcand":
        raise ConfigError(
            f"handshake_timeout_s: only interface 'socketcand' has a handshake,"
            f" got {handshake_timeout_s!r}"
        )
    if handshake_timeout_s is not None and (
        isinstance(handshake_timeout_s, bool)
        or not isinstance(handshake_timeout_s, int | float)
        or not 0 < handshake_timeout_s <= 3600
    ):
        raise ConfigError(
            f"handshake_timeout_s: must be a number of seconds in (0, 3600], "
            f"got {handshake_timeout_s!r}"
        )
    if interface == "socketcand":
        from gyrotherm.bus._socketcand import HANDSHAKE_TIMEOUT_S, SocketcandBus

        assert host is not None and port is not None  # _check_options
        _probe_socketcand(host, port, channel)
        return SocketcandBus.connect(
            host,
            port,
            channel,
            handshake_timeout_s=(
                HANDSHAKE_TIMEOUT_S if handshake_timeout_s is None else handshake_timeout_s
            ),
        )
    kwargs: dict[str, Any] = {"receive_own_messages": receive_own_messages}
    if bitrate is not None:
        kwargs["bitrate"] = bitrate
    if interface == "virtual":
        # keep the sender's timestamps: they carry the sensor (simulation) time
        kwargs["preserve_timestamps"] = True
    try:
        bus = can.Bus(interface=interface, channel=channel, ignore_config=True, **kwargs)
    except OSError as exc:
        if interface == "socketcan":
            raise _socketcan_error(channel, exc) from exc
        raise ConfigError(
            f"interface {interface!r}, channel {channel!r}: cannot open the bus ({exc})"
        ) from exc
    except can.CanError as exc:
        if interface == "socketcan" and isinstance(exc.__cause__, OSError):
            raise _socketcan_error(channel, exc.__cause__) from exc
        raise ConfigError(
            f"interface {interface!r}, channel {channel!r}: cannot open the bus ({exc})"
        ) from exc
    return BusAdapter(bus)
