"""Zenoh session configuration and key expressions, shared by the daemon and the client.

Safe defaults (no ``config_file``): zenoh's own defaults make a peer listen on
``tcp/[::]:0`` (a router on ``tcp/[::]:7447``) and scout by UDP multicast on
224.0.0.224:7446 and by gossip. :func:`session_config` instead builds a config with

* ``scouting/multicast/enabled = false`` and ``scouting/gossip/enabled = false``;
* ``listen/endpoints`` = exactly the endpoints asked for, ``[]`` when none (so a
  peer listens on nothing, it only connects); an endpoint on an unspecified
  address (``0.0.0.0``, ``[::]``) is refused unless ``allow_any_interface=True``;
* ``connect/endpoints`` = exactly the endpoints asked for.

With ``config_file`` the user's JSON5 file is loaded unchanged (deployments).

Key expressions: ``gyrotherm/<vehicle>/<sensor>/{rate,state,health,calibration}``;
vehicle and sensor names are 1-64 characters of ``[A-Za-z0-9_.-]``, not starting
with ``.`` or ``-`` (no ``/``, wildcards ``*``, ``$``, ``#``, ``?``, spaces...).
"""

from __future__ import annotations

import ipaddress
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import zenoh

from gyrotherm._errors import ConfigError

Mode = Literal["peer", "client", "router"]
MODES: tuple[Mode, ...] = ("peer", "client", "router")
KEY_PREFIX = "gyrotherm"
DEFAULT_CONNECT = ("tcp/127.0.0.1:7447",)

_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}")
_ENDPOINT = re.compile(r"(?P<proto>[A-Za-z0-9+-]+)/(?P<addr>[^?#]+)(?P<rest>[?#].*)?")


@dataclass(frozen=True)
class KeyExprs:
    """The key expressions of one sensor (see docs/wire-format.md)."""

    rate: str
    state: str
    health: str
    calibration: str


def _check_name(value: str, what: str) -> str:
    if not isinstance(value, str) or not _NAME.fullmatch(value):
        raise ConfigError(
            f"{what} name {value!r} is invalid: expected 1-64 characters of "
            "[A-Za-z0-9_.-] not starting with '.' or '-' (no '/', '*', '$', '#', '?')"
        )
    return value


def keys(vehicle: str, sensor: str) -> KeyExprs:
    """Return the four key expressions of ``vehicle``/``sensor``; ConfigError on a bad name."""
    base = f"{KEY_PREFIX}/{_check_name(vehicle, 'vehicle')}/{_check_name(sensor, 'sensor')}"
    return KeyExprs(f"{base}/rate", f"{base}/state", f"{base}/health", f"{base}/calibration")


def _host_of(addr: str) -> str:
    if addr.startswith("["):
        return addr[1 : addr.find("]")] if "]" in addr else addr
    return addr.rsplit(":", 1)[0] if ":" in addr else addr


def is_any_interface(endpoint: str) -> bool:
    """True when a ``proto/host:port`` endpoint names the unspecified address (all interfaces)."""
    m = _ENDPOINT.fullmatch(endpoint)
    if m is None:
        return False
    host = _host_of(m["addr"])
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return host in ("", "*", "0")  # "0" resolves to 0.0.0.0
    mapped = ip.ipv4_mapped if isinstance(ip, ipaddress.IPv6Address) else None
    return ip.is_unspecified or (mapped is not None and mapped.is_unspecified)


def _check_endpoints(endpoints: Sequence[str], what: str) -> list[str]:
    if isinstance(endpoints, str):
        raise ConfigError(f"{what} endpoints must be a list of strings, got str {endpoints!r}")
    out = []
    for ep in endpoints:
        if not isinstance(ep, str) or _ENDPOINT.fullmatch(ep) is None:
            raise ConfigError(
                f"{what} endpoint {ep!r} is invalid: expected '<proto>/<address>', "
                "e.g. 'tcp/127.0.0.1:7447'"
            )
        out.append(ep)
    return out


def _insert(config: zenoh.Config, key: str, value: object) -> None:
    try:
        config.insert_json5(key, json.dumps(value))
    except zenoh.ZError as exc:
        raise ConfigError(f"zenoh config {key} = {value!r} rejected: {exc}") from exc


def session_config(
    *,
    mode: Mode | None = None,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: str | Path | None = None,
    allow_any_interface: bool = False,
) -> zenoh.Config:
    """Build a :class:`zenoh.Config` with safe defaults (module docstring).

    ``mode`` defaults to ``"peer"``. A client needs at least one ``connect``
    endpoint and cannot listen. ``config_file`` excludes every other option: the
    file is passed to zenoh unchanged.
    """
    if config_file is not None:
        if mode is not None or listen or connect or allow_any_interface:
            raise ConfigError(
                f"config file {str(config_file)!r} given together with mode/listen/connect: "
                "put these settings in the file"
            )
        try:
            return zenoh.Config.from_file(str(config_file))
        except zenoh.ZError as exc:
            raise ConfigError(f"zenoh config file {str(config_file)!r}: {exc}") from exc
    mode = "peer" if mode is None else mode
    if mode not in MODES:
        raise ConfigError(f"zenoh mode {mode!r} is invalid: expected one of {MODES}")
    listen_eps = _check_endpoints(listen, "listen")
    connect_eps = _check_endpoints(connect, "connect")
    for ep in listen_eps:
        if is_any_interface(ep) and not allow_any_interface:
            raise ConfigError(
                f"listen endpoint {ep!r} listens on all interfaces: use an explicit "
                "address such as tcp/127.0.0.1:7447, or pass allow_any_interface=True"
            )
    if mode == "client":
        if listen_eps:
            raise ConfigError(f"zenoh client mode cannot listen (listen={listen_eps})")
        if not connect_eps:
            raise ConfigError("zenoh client mode needs at least one connect endpoint")
    config = zenoh.Config()
    _insert(config, "mode", mode)
    _insert(config, "scouting/multicast/enabled", False)
    _insert(config, "scouting/gossip/enabled", False)
    _insert(config, "listen/endpoints", listen_eps)
    _insert(config, "connect/endpoints", connect_eps)
    return config


def open_session(
    *,
    mode: Mode | None = None,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: str | Path | None = None,
    allow_any_interface: bool = False,
) -> zenoh.Session:
    """Open a zenoh session from :func:`session_config`; use it as a context manager.

    Raises ConfigError (naming the endpoints) when zenoh cannot open it, e.g. a
    listen port already in use or, in client mode, no reachable endpoint.
    """
    config = session_config(
        mode=mode,
        listen=listen,
        connect=connect,
        config_file=config_file,
        allow_any_interface=allow_any_interface,
    )
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        where = f"config file {str(config_file)!r}" if config_file else (
            f"mode={mode or 'peer'} listen={list(listen)} connect={list(connect)}"
        )
        raise ConfigError(f"cannot open zenoh session ({where}): {exc}") from exc
