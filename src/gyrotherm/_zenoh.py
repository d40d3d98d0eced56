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

The daemon's own session (``session_config(..., protect=keys(vehicle, sensor))``,
either way) additionally gets an access-control rule, :func:`protect_keys`: zenoh
drops every ``put``, ``delete``, ``declare_queryable``, ``reply`` and
``liveliness_token`` on ``gyrotherm/<vehicle>/<sensor>/**`` that arrives from any
other session (ingress, all remote faces), so nobody can publish or answer
calibration queries on the daemon's keys *through* the daemon's session, whatever
mode they connect in. The daemon's own publications are local, not ingress, and
subscriptions and queries stay allowed. zenoh matches a rule's key expression by
inclusion, so a forged message on a *wildcard* key (``gyrotherm/bench/*/rate``,
``**``) passes this rule: :class:`gyrotherm.client.Subscriber` accepts only samples
and replies on its exact keys, which such messages never are. Routers must enforce
their own ACL (deploy/zenoh/router.json5, acl-router.json5; docs/operations.md,
"Threat model").

Zenoh's error messages end with Rust source locations (``at /root/.cargo/…/x.rs:86.``);
:func:`zenoh_error_text` strips them before they reach a user.

Key expressions: ``gyrotherm/<vehicle>/<sensor>/{rate,state,health,calibration}``;
vehicle and sensor names are 1-64 characters of ``[A-Za-z0-9_.-]``, not starting
with ``.`` or ``-`` (no ``/``, wildcards ``*``, ``$``, ``#``, ``?``, spaces...).
"""

from __future__ import annotations

import ipaddress
import json
import logging
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import zenoh

from gyrotherm._errors import ConfigError

Mode = Literal["peer", "client", "router"]
MODES: tuple[Mode, ...] = ("peer", "client", "router")
KEY_PREFIX = "gyrotherm"
DEFAULT_CONNECT = ("tcp/127.0.0.1:7447",)

#: What no other session may send on the daemon's keys (zenoh ACL message names).
PROTECTED_MESSAGES = ("put", "delete", "declare_queryable", "reply", "liveliness_token")
#: ids of the access-control entries :func:`protect_keys` adds.
ACL_RULE_ID = "gyrotherm-protect-keys"
ACL_SUBJECT_ID = "gyrotherm-any-remote"
ACL_POLICY_ID = "gyrotherm-protect-keys"
#: The password shipped in deploy/zenoh/client-of-router.json5: refused, so a file
#: installed without setting a real password never authenticates anybody.
PLACEHOLDER_PASSWORD = "REPLACE-WITH-A-SECRET"

log = logging.getLogger("gyrotherm.zenoh")

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


_RUST_LOCATION = re.compile(
    r"\s*(?:\bat\s+[^\s()]+?\.rs:\d+(?::\d+)?\.?"  # ... at /root/.cargo/.../config.rs:86.
    r"|\(\s*[^\s()]+?\.rs:\d+(?::\d+)?\s*\))"  # (.../src/x.rs:10:5)
)
_JSON5_MESSAGE = re.compile(
    r'(?:Json5Err\()?Message \{ msg: "(?P<msg>(?:[^"\\]|\\.)*)", location: '
    r"(?:Some\(Location \{ line: (?P<line>\d+), column: (?P<col>\d+) \}\)|None) \}\)?"
)

_PEST_ERROR = re.compile(r"-->\s*(?P<line>\d+):(?P<col>\d+)\s*\n.*\n\s*=\s*(?P<msg>[^\n]+)", re.S)


def zenoh_error_text(exc: BaseException | str) -> str:
    """A zenoh error's message without Rust source locations and debug wrappers.

    ``'Json5Err(Message { msg: "unknown variant `server`", location: Some(Location
    { line: 1, column: 1 }) }) at /root/.cargo/.../config.rs:86.'`` becomes
    ``'unknown variant `server` (line 1, column 1)'``.
    """
    text = _RUST_LOCATION.sub("", str(exc))

    def plain(m: re.Match[str]) -> str:
        msg = m["msg"].replace('\\"', '"').replace("\\\\", "\\")
        return f"{msg} (line {m['line']}, column {m['col']})" if m["line"] else msg

    text = _JSON5_MESSAGE.sub(plain, text)
    pest = _PEST_ERROR.fullmatch(text.strip())
    if pest:  # json5's multi-line syntax error drawing -> one line
        text = f"{pest['msg']} (line {pest['line']}, column {pest['col']})"
    text = re.sub(r'^Str\("(.*)"\)$', r"\1", text.strip())
    return text.strip().rstrip(".").strip() or type(exc).__name__


def _insert(config: zenoh.Config, key: str, value: object, source: str = "zenoh config") -> None:
    try:
        config.insert_json5(key, json.dumps(value))
    except zenoh.ZError as exc:
        raise ConfigError(
            f"{source}: {key} = {value!r} rejected: {zenoh_error_text(exc)}"
        ) from exc


def _get(config: zenoh.Config, key: str, source: str) -> Any:
    try:
        return json.loads(config.get_json(key))
    except zenoh.ZError as exc:
        raise ConfigError(f"{source}: cannot read {key}: {zenoh_error_text(exc)}") from exc


def _endpoints_for_mode(config: zenoh.Config, key: str, source: str) -> list[str]:
    value = _get(config, key, source)
    if isinstance(value, Mapping):
        value = value.get(_get(config, "mode", source) or "peer", [])
    return [str(v) for v in value or []]


def _is_multicast(endpoint: str) -> bool:
    m = _ENDPOINT.fullmatch(endpoint)
    if m is None:
        return False
    try:
        return ipaddress.ip_address(_host_of(m["addr"])).is_multicast
    except ValueError:
        return False


Protected = KeyExprs | Sequence[KeyExprs | str]
"""What :func:`protect_keys` protects: one sensor's keys, or several sensors' keys and
key prefixes (a daemon with several IMUs: each sensor and ``gyrotherm/<vehicle>/consistency``)."""


def _prefixes(protected: Protected) -> list[str]:
    items = [protected] if isinstance(protected, KeyExprs) else list(protected)
    return [i.rate.rsplit("/", 1)[0] if isinstance(i, KeyExprs) else i for i in items]


def protect_keys(config: zenoh.Config, sensor_keys: Protected, *, source: str) -> zenoh.Config:
    """Add the daemon's access-control rule to ``config`` (in place) and return it.

    Every remote session (any mode, any link, any identity) is denied *ingress*
    :data:`PROTECTED_MESSAGES` on ``gyrotherm/<vehicle>/<sensor>/**``; everything
    else keeps the config's own permissions. With ``access_control`` disabled
    (also zenoh's default when the file has none) the block becomes exactly this
    rule with ``default_permission: "allow"``. A file with its own *enabled*
    access control gets the rule, its subject and policy merged in: zenoh lets a
    deny rule win over any allow, so the merge can only take rights away, and only
    these; the file's ``default_permission`` and rules are kept. ids already used
    by the file, and multicast transports (zenoh applies no ACL to them), are
    refused with a ConfigError naming ``source``.
    """
    for key in ("listen/endpoints", "connect/endpoints"):
        for ep in _endpoints_for_mode(config, key, source):
            if _is_multicast(ep):
                raise ConfigError(
                    f"{source}: {key} {ep!r} is a multicast transport: zenoh's access "
                    "control does not apply to it, so anyone on that group could publish "
                    "as the daemon; use unicast endpoints"
                )
    prefixes = _prefixes(sensor_keys)
    prefix = ", ".join(prefixes)
    rule = {
        "id": ACL_RULE_ID,
        "permission": "deny",
        "flows": ["ingress"],
        "messages": list(PROTECTED_MESSAGES),
        "key_exprs": [f"{p}/**" for p in prefixes],
    }
    subject = {"id": ACL_SUBJECT_ID}  # no property: matches every remote session
    policy = {"id": ACL_POLICY_ID, "rules": [ACL_RULE_ID], "subjects": [ACL_SUBJECT_ID]}
    acl = _get(config, "access_control", source)
    if not isinstance(acl, Mapping) or not acl.get("enabled"):
        merged: dict[str, Any] = {
            "enabled": True,
            "default_permission": "allow",
            "rules": [rule],
            "subjects": [subject],
            "policies": [policy],
        }
        how = "added"
    else:
        merged = dict(acl)
        for field, entry in (("rules", rule), ("subjects", subject), ("policies", policy)):
            existing = list(merged.get(field) or [])
            taken = [e.get("id") for e in existing if isinstance(e, Mapping)]
            if entry["id"] in taken:
                raise ConfigError(
                    f"{source}: access_control/{field} already has id {entry['id']!r}, "
                    "which gyrotherm reserves for the rule protecting its keys: rename it"
                )
            merged[field] = [*existing, entry]
        how = f"merged into the file's access_control (default_permission " \
              f"{merged.get('default_permission', 'deny')!r} kept)"
    _insert(config, "access_control", merged, source)
    log.info("zenoh access control: ingress %s on %s/** denied from every other session "
             "(%s, %s)", "/".join(PROTECTED_MESSAGES), prefix, source, how)
    return config


def _check_password(config: zenoh.Config, source: str) -> None:
    if _get(config, "transport/auth/usrpwd/password", source) == PLACEHOLDER_PASSWORD:
        raise ConfigError(
            f"{source}: transport/auth/usrpwd/password is still the shipped placeholder "
            f"{PLACEHOLDER_PASSWORD!r}: set the password the router's dictionary file "
            "has for this user (docs/operations.md, \"Threat model\")"
        )


def session_config(
    *,
    mode: Mode | None = None,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: str | Path | None = None,
    allow_any_interface: bool = False,
    protect: Protected | None = None,
) -> zenoh.Config:
    """Build a :class:`zenoh.Config` with safe defaults (module docstring).

    ``mode`` defaults to ``"peer"``. A client needs at least one ``connect``
    endpoint and cannot listen. ``config_file`` excludes every other option: the
    file is passed to zenoh unchanged, except that a ``transport/auth/usrpwd``
    password still equal to :data:`PLACEHOLDER_PASSWORD` is refused. ``protect``
    (the daemon's keys) adds the access-control rule of :func:`protect_keys`.
    """
    if config_file is not None:
        if mode is not None or listen or connect or allow_any_interface:
            raise ConfigError(
                f"config file {str(config_file)!r} given together with mode/listen/connect: "
                "put these settings in the file"
            )
        source = f"zenoh config file {str(config_file)!r}"
        try:
            config = zenoh.Config.from_file(str(config_file))
        except zenoh.ZError as exc:
            raise ConfigError(f"{source}: {zenoh_error_text(exc)}") from exc
        _check_password(config, source)
        return config if protect is None else protect_keys(config, protect, source=source)
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
    if protect is not None:
        where = f"zenoh mode={mode} listen={listen_eps} connect={connect_eps}"
        protect_keys(config, protect, source=where)
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
        raise ConfigError(
            f"cannot open zenoh session ({where}): {zenoh_error_text(exc)}"
        ) from exc
