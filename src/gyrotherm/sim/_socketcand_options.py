"""Option checks and the per-client counters of the socketcand server.

:class:`~gyrotherm.sim._socketcand.SocketcandServer` checks its keyword options
here before it binds anything; every bad value raises
:class:`gyrotherm.ConfigError` naming the option, the limit and the value:

* ``host``: a non-empty address string;
* ``port``: an integer in 0..65535 (0: an ephemeral port);
* ``channel``: 1 to 16 characters without spaces (a Linux interface name);
* queue and client limits (:func:`_positive`): integers >= 1 (``bool`` rejected).

:class:`ClientStats` is the frozen value
:meth:`~gyrotherm.sim._socketcand.SocketcandServer.client_stats` returns; it is
re-exported from :mod:`gyrotherm.sim` and :mod:`gyrotherm.sim._socketcand`.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrotherm._errors import ConfigError


@dataclass(frozen=True)
class ClientStats:
    """Counters of one client connection (``peer`` is ``"host:port"``)."""

    peer: str
    connected: bool
    frames_sent: int
    frames_dropped: int


def _positive(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{name}: must be an integer >= 1, got {value!r}")
    return value


def _check_endpoint(host: str, port: int, channel: str) -> None:
    """Raise :class:`gyrotherm.ConfigError` for a bad ``host``, ``port`` or ``channel``."""
    if not isinstance(host, str) or not host:
        raise ConfigError(f"host: must be a non-empty address, got {host!r}")
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError(f"port: must be an integer in 0..65535 (0: ephemeral), got {port!r}")
    if not isinstance(channel, str) or not 0 < len(channel) <= 16 or " " in channel:
        raise ConfigError(f"channel: must be 1 to 16 characters without spaces, got {channel!r}")
