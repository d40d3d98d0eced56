"""Several IMUs in one configuration: ``[[imu]]`` tables and ``[consistency]``.

A configuration without ``[[imu]]`` tables is today's single-IMU one and reads
unchanged (:func:`gyrotherm.daemon._config.parse_config`). With them, the
top-level keys and tables (vehicle, bus, Zenoh, estimator, zero, state_dir …)
are shared, and each ``[[imu]]`` table names one IMU::

    vehicle = "veh01"
    [can]
    interface = "socketcan"
    channel = "can0"
    [zenoh]
    config = "/etc/gyrotherm/zenoh.json5"

    [[imu]]
    sensor = "imu0"                                   # required, unique
    calibration = "/var/lib/gyrotherm/imu0.calibration.json"   # optional
    device_id = "2490378"                             # optional, as at top level
    device_mismatch = "refuse"                        # optional
    dbc = "imu0.dbc"                                  # optional: overrides [can] dbc
    signals = { rate_frame_id = 0x120, temperature_frame_id = 0x121 }
                         # optional: keys over [can.signals] (or the shipped map)
    learn = { enabled = false }                       # optional: keys over [learn]
    listen = ["tcp/127.0.0.1:7448"]                   # optional: [zenoh] listen when this
                                                      # IMU runs alone (run --imu; ignored
                                                      # when one process runs them all)
    [[imu]]
    sensor = "imu1"
    signals = { rate_frame_id = 0x122, temperature_frame_id = 0x123 }

    [consistency]            # optional; on by default with two IMUs or more
    enabled = true
    window_s = 0.5           # window of time-aligned differences, s
    tolerance_dps = 0.1      # disagreement the calibrations may leave, °/s
    k_sigma = 4.0            # noise multiple added to the tolerance
    max_skew_s = 0.005       # two samples further apart than this are not paired, s
    min_samples = 20         # fewer pairs in a window: "no data"

Each IMU becomes one :class:`DaemonConfig` (validated by ``parse_config``, its
errors prefixed ``<file>: [[imu]] #<index>``); IMUs on one bus must not share a
frame id. ``sensor``, ``calibration``, ``device_id`` and ``device_mismatch`` are
per IMU and refused at the top level of such a file; the sensor name
``consistency`` is reserved (``gyrotherm/<vehicle>/consistency/<a>/<b>``).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import SignalMap
from gyrotherm.codecs._canmap import resolve_layout
from gyrotherm.daemon._config import DaemonConfig, parse_config

IMU_KEYS = frozenset({"sensor", "calibration", "device_id", "device_mismatch", "dbc",
                      "signals", "listen", "learn"})
PER_IMU_TOP_KEYS = ("sensor", "calibration", "device_id", "device_mismatch")
RESERVED_SENSORS = frozenset({"consistency"})


@dataclass(frozen=True)
class ConsistencyConfig:
    """How two IMUs' corrected rates are compared (:mod:`gyrotherm.daemon._consistency`)."""

    window_s: float = 0.5
    tolerance_dps: float = 0.1
    k_sigma: float = 4.0
    max_skew_s: float = 0.005
    min_samples: int = 20


@dataclass(frozen=True)
class VehicleConfig:
    """The IMUs one ``gyrotherm run`` serves; ``multi``: written with ``[[imu]]`` tables."""

    imus: tuple[DaemonConfig, ...]
    consistency: ConsistencyConfig | None = None
    multi: bool = False
    source: str = "<memory>"
    alone: tuple[DaemonConfig, ...] = ()
    """Each IMU as ``run --imu`` runs it: with its table's ``listen`` (else = ``imus``)."""

    @property
    def sensors(self) -> tuple[str, ...]:
        return tuple(c.sensor for c in self.imus)

    def only(self, sensor: str) -> VehicleConfig:
        """The one IMU named ``sensor`` (``run --imu``), with its own ``listen``."""
        for cfg in self.alone or self.imus:
            if cfg.sensor == sensor:
                return VehicleConfig((cfg,), None, False, self.source)
        raise ConfigError(f"{self.source}: --imu {sensor!r}: no [[imu]] table has that sensor; "
                          f"the file has {list(self.sensors)}")


def _consistency(table: Any, where: str) -> ConsistencyConfig | None:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: must be a table, got {table!r}")
    known = {f.name for f in dataclasses.fields(ConsistencyConfig)} | {"enabled"}
    extra = sorted(set(table) - known)
    if extra:
        raise ConfigError(f"{where}: unknown key(s) {extra}; known: {sorted(known)}")
    enabled = table.get("enabled", True)
    if not isinstance(enabled, bool):
        raise ConfigError(f"{where}: enabled must be true or false, got {enabled!r}")
    bounds = {"window_s": (0.05, 60.0), "tolerance_dps": (0.0, 100.0), "k_sigma": (0.0, 100.0),
              "max_skew_s": (1e-4, 1.0), "min_samples": (2, 10**7)}
    values: dict[str, Any] = {}
    for name, (lo, hi) in bounds.items():
        if name not in table:
            continue
        v = table[name]
        is_int = name == "min_samples"
        if isinstance(v, bool) or not isinstance(v, int if is_int else (int, float)) \
                or not (math.isfinite(v) and lo <= v <= hi):
            kind = "an integer" if is_int else "a number"
            raise ConfigError(f"{where}: {name} = {v!r} must be {kind} in [{lo:g}, {hi:g}]")
        values[name] = v if is_int else float(v)
    return ConsistencyConfig(**values) if enabled else None


def _imu_doc(base: dict[str, Any], imu: dict[str, Any], *, alone: bool) -> dict[str, Any]:
    """The single-IMU document of one ``[[imu]]`` table over the shared keys."""
    doc = dict(base)
    for key in PER_IMU_TOP_KEYS:
        if key in imu:
            doc[key] = imu[key]
    can = dict(base.get("can", {})) if isinstance(base.get("can"), dict) else base.get("can", {})
    if "dbc" in imu and isinstance(can, dict):
        can["dbc"] = imu["dbc"]
    if "signals" in imu and isinstance(can, dict):
        if not isinstance(imu["signals"], dict):
            raise ConfigError(f"signals must be a table, got {imu['signals']!r}")
        shared = can.get("signals") or dataclasses.asdict(SignalMap.default())
        can["signals"] = {**shared, **imu["signals"]}
    doc["can"] = can
    if "learn" in imu:  # this IMU's keys over the shared [learn] table
        if not isinstance(imu["learn"], dict):
            raise ConfigError(f"learn must be a table, got {imu['learn']!r}")
        shared_learn = base.get("learn", {})
        doc["learn"] = {**(shared_learn if isinstance(shared_learn, dict) else {}),
                        **imu["learn"]}
    if alone and "listen" in imu:
        zen = base.get("zenoh", {})
        doc["zenoh"] = {**(zen if isinstance(zen, dict) else {}), "listen": imu["listen"]}
    return doc


def parse_vehicle_config(data: dict[str, Any], *, source: str = "<memory>",
                         base_dir: Path | None = None) -> VehicleConfig:
    """Validate a parsed TOML document with or without ``[[imu]]`` tables."""
    if "imu" not in data:
        if "consistency" in data:
            raise ConfigError(f"{source}: [consistency] needs [[imu]] tables (several IMUs)")
        return VehicleConfig((parse_config(data, source=source, base_dir=base_dir),),
                             source=source)
    tables = data["imu"]
    if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
        raise ConfigError(f"{source}: imu must be one or more [[imu]] tables, got {tables!r}")
    for key in PER_IMU_TOP_KEYS:
        if key in data:
            raise ConfigError(f"{source}: {key} = {data[key]!r} at the top level: with [[imu]] "
                              f"tables, '{key}' belongs in each [[imu]] table")
    base = {k: v for k, v in data.items() if k not in ("imu", "consistency")}
    imus: list[DaemonConfig] = []
    alone: list[DaemonConfig] = []
    owners: dict[int, str] = {}
    for i, table in enumerate(tables):
        where = f"{source}: [[imu]] #{i}"
        extra = sorted(set(table) - IMU_KEYS)
        if extra:
            raise ConfigError(f"{where}: unknown key(s) {extra}; known: {sorted(IMU_KEYS)}")
        if "sensor" not in table:
            raise ConfigError(f"{where}: key 'sensor' is required")
        sensor = table["sensor"]
        if sensor in RESERVED_SENSORS:
            raise ConfigError(f"{where}: sensor = {sensor!r} is reserved (consistency keys)")
        try:
            cfg = parse_config(_imu_doc(base, table, alone=False), source=where,
                               base_dir=base_dir)
            alone.append(parse_config(_imu_doc(base, table, alone=True), source=where,
                                      base_dir=base_dir))
        except ConfigError as exc:
            msg = str(exc)
            raise ConfigError(msg if msg.startswith(where) else f"{where}: {msg}") from exc
        if cfg.sensor in {c.sensor for c in imus}:
            raise ConfigError(f"{where}: sensor = {cfg.sensor!r} is already used by another "
                              "[[imu]] table")
        try:
            layout = resolve_layout(cfg.can.dbc, cfg.can.signals)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from exc
        for plan in (layout.rate, layout.temperature):
            other = owners.get(plan.key)
            if other is not None:
                raise ConfigError(f"{where}: message {plan.name!r} at frame id "
                                  f"{plan.frame_id:#x} is also {other}'s: IMUs on one bus need "
                                  "their own ids (signals = { rate_frame_id = …, "
                                  "temperature_frame_id = … })")
            owners[plan.key] = f"[[imu]] #{i} ({cfg.sensor})"
        imus.append(cfg)
    cons = data.get("consistency", {})
    consistency = _consistency(cons, f"{source}: [consistency]") if len(imus) > 1 else None
    return VehicleConfig(tuple(imus), consistency, True, source, tuple(alone))


def load_vehicle_config(path: str | Path) -> VehicleConfig:
    """Read and validate a TOML config file, one IMU or several."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read config file: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from exc
    return parse_vehicle_config(data, source=str(p), base_dir=p.parent.resolve())
