"""The daemon's TOML configuration, validated into frozen, typed objects.

Example (every key; relative paths are relative to the config file)::

    vehicle = "veh01"                 # key prefix gyrotherm/<vehicle>/<sensor>/
    sensor = "imu0"
    calibration = "/var/lib/gyrotherm/imu0.calibration.json"   # optional
    health_period_s = 1.0             # health publication period, s
    state_dir = "/var/lib/gyrotherm"  # optional: keep the effects' state across restarts
    power_on_gap_s = 30.0             # sensor silence after which the gyro counts as
                                      # powered on again (t_on = 0), s
    device_id = "2490378"             # optional: the IMU the calibration must be for
    device_mismatch = "refuse"        # refuse | warn (with device_id)

    [can]
    interface = "socketcan"           # socketcan | socketcand | virtual
    channel = "can0"
    bitrate = 500000                  # bit/s, optional (socketcan)
    host = "127.0.0.1"                # socketcand only
    port = 29536                      # socketcand only
    dbc = "gyro.dbc"                  # optional, default: the shipped DBC
    on_counter_jump = "deliver"       # deliver | reject
    recv_timeout_s = 0.2              # longest wait for a frame before housekeeping, s
    reopen_after_s = 5.0              # no frame for this long: close and reopen the bus, s
    start_timeout_s = 20.0            # at start, retry opening the bus this long, then exit 2, s

    [can.signals]                     # optional: message/signal names in your DBC
    rate_message = "GyroRate"         # (all SignalMap fields, see docs/wire-format.md)

    [estimator]                       # optional, used only without a calibration
    stale_after_s = 5.0

    [zero]                            # optional: boot-time zero at rest (off without
    window_s = 10.0                   # the table); every key optional, defaults shown:
    settle_s = 30.0                   # wait after power-on before the first window, s
    max_std_dps = 0.5                 # rest check: std of rate − bias per axis, °/s
    max_step_dps = 0.05               # rest check: half-window means differ by ≤, °/s
    max_offset_dps = 1.0              # largest offset taken for a switch-on offset, °/s
    deadline_s = 600.0                # no rest window this long after power-on: failed, s

    [learn]                           # optional: learn a calibration from the warm-ups
    margin_frac = 0.10                # at rest after each power-on (off without the
                                      # table; keys: gyrotherm.daemon._learn_config)

    [zenoh]
    config = "/etc/gyrotherm/zenoh.json5"   # a Zenoh JSON5 file, passed through; or:
    mode = "peer"                           # peer | client | router
    listen = ["tcp/127.0.0.1:7447"]         # default; [] in client mode
    connect = []
    publish_block_max_s = 0.5               # longest a rate/state put may block on a full
                                            # link before zenoh drops that link, s

``start_timeout_s`` (0.5…600 s) must leave room in the unit's ``TimeoutStartSec=30s``
for the Zenoh session to open. ``publish_block_max_s``
(0.01…2 s) is written into the session config as zenoh's
``transport/link/tx/queue/congestion_control/block/wait_before_close`` (µs), also
over a ``config`` file's value; it must stay well under half of ``WatchdogSec=5s``
(docs/operations.md, "A slow or frozen subscriber").

``state_dir`` (default: none, no persistence) is where the daemon keeps the
calibration effects' state (``<vehicle>.<sensor>.effects-state.json``, written
every 5 s and at shutdown) so that a restart while the gyro keeps running does
not replay its warm-up; under the shipped unit it is the ``StateDirectory=``
``/var/lib/gyrotherm``. Power-on (t_on = 0) is the first temperature frame after
the start, after a silence longer than ``power_on_gap_s`` (1…3600 s) or after a
time base change; a saved state is restored only for the same calibration id
when the first frame continues its time within ``power_on_gap_s``
(docs/operations.md, "Calibration effects across restarts").

``[zero]`` (default: absent, no zero) turns on the boot-time zero
(:mod:`gyrotherm.compensation._zero`, docs/model.md "Boot-time zero"): after
each power-on the daemon measures the switch-on offset the calibration cannot
know over ``window_s`` at rest, and removes it with the calibration's bias.
Only with a calibration; the vehicle must be at rest after power-on.

``device_id`` (default: none, nothing compared) is the IMU this sensor is (the
``device_id`` that ``fit`` records in a calibration's provenance); a calibration
recording another device is refused at start and on reload, or only logged with
``device_mismatch = "warn"`` (:mod:`gyrotherm.daemon._calload`).

``[learn]`` (default: absent, no learning) learns a paper-model calibration from
the warm-ups at rest after each power-on and adopts it only when held-out warm-ups
show it better (:mod:`gyrotherm.daemon._learner`, docs/operations.md "Learning a
calibration on the vehicle"); it needs ``state_dir`` and ``[zero]`` (the learnt level
is not validated: the boot-time zero measures each power-on's).

Errors are :class:`gyrotherm.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gyrotherm._errors import ConfigError
from gyrotherm._zenoh import keys, session_config
from gyrotherm.codecs import DEFAULT_DBC_PATH, SignalMap
from gyrotherm.compensation._zero import ZeroConfig
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.estimators import EstimatorConfig

INTERFACES = ("socketcan", "socketcand", "virtual")


@dataclass(frozen=True)
class CanConfig:
    """Where the frames come from and how to read them."""

    interface: str = "socketcan"
    channel: str = "can0"
    bitrate: int | None = None
    host: str | None = None
    port: int | None = None
    dbc: Path = DEFAULT_DBC_PATH
    signals: SignalMap = field(default_factory=SignalMap.default)
    on_counter_jump: str = "deliver"
    recv_timeout_s: float = 0.2
    reopen_after_s: float = 5.0
    start_timeout_s: float = 20.0


@dataclass(frozen=True)
class ZenohConfig:
    """The Zenoh session: a user's JSON5 file, or loopback-safe explicit endpoints."""

    config_file: Path | None = None
    mode: str = "peer"
    listen: tuple[str, ...] = ("tcp/127.0.0.1:7447",)
    connect: tuple[str, ...] = ()
    publish_block_max_s: float = 0.5


@dataclass(frozen=True)
class DaemonConfig:
    """Everything ``gyrotherm run`` needs."""

    vehicle: str
    sensor: str
    can: CanConfig
    zenoh: ZenohConfig
    calibration: Path | None = None
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    health_period_s: float = 1.0
    state_dir: Path | None = None
    power_on_gap_s: float = 30.0
    zero: ZeroConfig | None = None
    device_id: str | None = None
    device_mismatch: str = "refuse"
    learn: LearnConfig | None = None
    source: str = "<memory>"


def _table(data: dict[str, Any], key: str, where: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: [{key}] must be a table, got {value!r}")
    return value


def _take(table: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str,
          default: Any) -> Any:
    if key not in table:
        return default
    value = table[key]
    if (isinstance(value, bool) and kind is not bool) or not isinstance(value, kind):
        want = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise ConfigError(f"{where}: key {key!r} must be {want}, got {value!r}")
    return value


def _unknown(table: dict[str, Any], known: set[str], where: str) -> None:
    extra = sorted(set(table) - known)
    if extra:
        raise ConfigError(f"{where}: unknown key(s) {extra}; known: {sorted(known)}")


def _bounded(value: float, lo: float, hi: float, what: str) -> float:
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"{what} = {value!r} is outside [{lo:g}, {hi:g}]")
    return float(value)


def _path(base: Path, value: str) -> Path:
    p = Path(value).expanduser()
    return p if p.is_absolute() else base / p


def parse_config(data: dict[str, Any], *, source: str = "<memory>",
                 base_dir: Path | None = None) -> DaemonConfig:
    """Validate a parsed TOML document."""
    base = base_dir or Path.cwd()
    if "imu" in data:
        raise ConfigError(f"{source}: [[imu]] tables describe several IMUs: read it with "
                          "gyrotherm.daemon.load_vehicle_config (gyrotherm run does)")
    _unknown(data, {"vehicle", "sensor", "calibration", "health_period_s", "can", "estimator",
                    "zenoh", "state_dir", "power_on_gap_s", "zero", "device_id",
                    "device_mismatch", "learn"}, source)
    vehicle = _take(data, "vehicle", str, source, None)
    sensor = _take(data, "sensor", str, source, None)
    if vehicle is None or sensor is None:
        raise ConfigError(f"{source}: keys 'vehicle' and 'sensor' are required")
    try:
        keys(vehicle, sensor)  # validates the names
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from exc
    cal = _take(data, "calibration", str, source, None)
    health = _bounded(_take(data, "health_period_s", (int, float), source, 1.0), 0.05, 3600,
                      f"{source}: health_period_s")
    state_dir = _take(data, "state_dir", str, source, None)
    if state_dir is not None and not state_dir.strip():
        raise ConfigError(f"{source}: state_dir = {state_dir!r}: must name a directory")
    gap = _bounded(_take(data, "power_on_gap_s", (int, float), source, 30.0), 1.0, 3600.0,
                   f"{source}: power_on_gap_s")
    device_id = _take(data, "device_id", str, source, None)
    mismatch = _take(data, "device_mismatch", str, source, "refuse")
    if mismatch not in ("refuse", "warn"):
        raise ConfigError(f"{source}: device_mismatch {mismatch!r} is not 'refuse' or 'warn'")

    where = f"{source}: [can]"
    c = _table(data, "can", source)
    _unknown(c, {"interface", "channel", "bitrate", "host", "port", "dbc", "signals",
                 "on_counter_jump", "recv_timeout_s", "reopen_after_s", "start_timeout_s"}, where)
    interface = _take(c, "interface", str, where, "socketcan")
    if interface not in INTERFACES:
        raise ConfigError(f"{where}: interface {interface!r} is not one of {INTERFACES}")
    bitrate = _take(c, "bitrate", int, where, None)
    if bitrate is not None and not 10_000 <= bitrate <= 1_000_000:
        raise ConfigError(f"{where}: bitrate = {bitrate} is outside [10000, 1000000] bit/s "
                          "(classic CAN)")
    port = _take(c, "port", int, where, None)
    if port is not None and not 1 <= port <= 65535:
        raise ConfigError(f"{where}: port = {port} is outside [1, 65535]")
    host = _take(c, "host", str, where, None)
    if interface == "socketcand" and (host is None or port is None):
        raise ConfigError(f"{where}: interface 'socketcand' needs 'host' and 'port'")
    if interface != "socketcand" and (host is not None or port is not None):
        raise ConfigError(f"{where}: 'host' and 'port' apply only to interface 'socketcand'")
    jump = _take(c, "on_counter_jump", str, where, "deliver")
    if jump not in ("deliver", "reject"):
        raise ConfigError(f"{where}: on_counter_jump {jump!r} is not 'deliver' or 'reject'")
    dbc = _take(c, "dbc", str, where, None)
    signals_table = _table(c, "signals", where)
    signals = (SignalMap.from_dict(signals_table, source=f"{where}.signals") if signals_table
               else SignalMap.default())
    can = CanConfig(
        interface=interface,
        channel=_take(c, "channel", str, where, "can0"),
        bitrate=bitrate,
        host=host,
        port=port,
        dbc=DEFAULT_DBC_PATH if dbc is None else _path(base, dbc),
        signals=signals,
        on_counter_jump=jump,
        recv_timeout_s=_bounded(_take(c, "recv_timeout_s", (int, float), where, 0.2), 0.001,
                                2.0, f"{where}: recv_timeout_s"),
        reopen_after_s=_bounded(_take(c, "reopen_after_s", (int, float), where, 5.0), 0.5,
                                3600.0, f"{where}: reopen_after_s"),
        start_timeout_s=_bounded(_take(c, "start_timeout_s", (int, float), where, 20.0), 0.5,
                                 600.0, f"{where}: start_timeout_s"),
    )

    where = f"{source}: [zenoh]"
    z = _table(data, "zenoh", source)
    _unknown(z, {"config", "mode", "listen", "connect", "publish_block_max_s"}, where)
    zfile = _take(z, "config", str, where, None)
    if zfile is not None and ({"mode", "listen", "connect"} & set(z)):
        raise ConfigError(f"{where}: 'config' excludes 'mode', 'listen' and 'connect'")
    mode = _take(z, "mode", str, where, "peer")
    if mode not in ("peer", "client", "router"):
        raise ConfigError(f"{where}: mode {mode!r} is not 'peer', 'client' or 'router'")
    listen = _take(z, "listen", list, where,
                   [] if mode == "client" else ["tcp/127.0.0.1:7447"])
    connect = _take(z, "connect", list, where, [])
    for name, eps in (("listen", listen), ("connect", connect)):
        if not all(isinstance(e, str) for e in eps):
            raise ConfigError(f"{where}: {name} must be a list of endpoint strings, got {eps!r}")
    if zfile is None:  # the same checks the session will make, now, naming the file
        try:
            session_config(mode=mode, listen=listen, connect=connect)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from exc
    zenoh = ZenohConfig(
        config_file=None if zfile is None else _path(base, zfile),
        mode=mode,
        listen=tuple(listen),
        connect=tuple(connect),
        publish_block_max_s=_bounded(_take(z, "publish_block_max_s", (int, float), where, 0.5),
                                     0.01, 2.0, f"{where}: publish_block_max_s"),
    )
    est_table = _table(data, "estimator", source)
    zero = (ZeroConfig.from_dict(_table(data, "zero", source), where=f"{source}: [zero]")
            if "zero" in data else None)
    learn = (LearnConfig.from_dict(_table(data, "learn", source), where=f"{source}: [learn]")
             if "learn" in data else None)
    if learn is not None and state_dir is None:
        raise ConfigError(f"{source}: [learn] needs state_dir (the learnt statistics and "
                          "the adopted calibration are kept there)")
    if learn is not None and zero is None:
        raise ConfigError(f"{source}: [learn] needs [zero]: learning validates the shape of "
                          "the bias within each warm-up, its level is only the mean of the "
                          "power-ons' switch-on offsets; the boot-time zero removes each "
                          "power-on's own (without it a learnt calibration can be worse than "
                          "none)")
    return DaemonConfig(
        vehicle=vehicle,
        sensor=sensor,
        can=can,
        zenoh=zenoh,
        calibration=None if cal is None else _path(base, cal),
        estimator=EstimatorConfig.from_dict(est_table, where=f"{source}: [estimator]"),
        health_period_s=health,
        state_dir=None if state_dir is None else _path(base, state_dir),
        power_on_gap_s=gap,
        zero=zero,
        device_id=device_id,
        device_mismatch=mismatch,
        learn=learn,
        source=source,
    )


def load_config(path: str | Path) -> DaemonConfig:
    """Read and validate a TOML config file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read config file: {exc}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from exc
    return parse_config(data, source=str(p), base_dir=p.parent.resolve())
