"""The user's input options (:class:`InputSpec`) and the column map of ``--columns``.

A column map assigns roles to columns of a delimited text file, one token per
role, ``ROLE=COLUMN[:UNIT]``::

    time=timestamp:us temperature=temp:degC x=gx:rad/s y=gy:rad/s z=gz:rad/s

Roles: ``time``, ``temperature`` (required), ``x``, ``y``, ``z`` (angular rate,
at least one), ``accel_x``, ``accel_y``, ``accel_z`` (optional), each with a
unit from :data:`gyrotherm.readers._units.UNITS`; and two grouping roles without
a unit, ``device`` (a device id column: one run per device) and ``run`` (a
segment/session label column: one run per label). The unit is split off at the
last ``:`` so column names may contain ``:`` themselves. A file without a header
names its columns by number, from 1 (``temperature=1:degC x=5:dps``).

A log without time stamps (a serial capture printing samples at a fixed rate) has no
``time`` role: the map then carries the nominal sample rate (``--rate-hz``), and each
run's time is its row index / rate, recorded as nominal in its metadata.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import SignalMap
from gyrotherm.readers._units import UNITS, Kind, Unit, unit_names

MEASURED_ROLES: dict[str, Kind] = {
    "time": "time", "temperature": "temperature",
    "x": "rate", "y": "rate", "z": "rate",
    "accel_x": "accel", "accel_y": "accel", "accel_z": "accel",
}
"""Roles that carry a measurement, and the kind of unit each takes."""
GROUP_ROLES = ("device", "run")
"""Roles that split the rows into runs (no unit)."""
RATE_ROLES = ("x", "y", "z")
ACCEL_EXTRA = {"accel_x": "accel_x_mps2", "accel_y": "accel_y_mps2", "accel_z": "accel_z_mps2"}
"""Accelerometer roles → the :attr:`Run.extra` key they are stored under (m/s²)."""
EXAMPLE_COLUMNS = "time=timestamp:us temperature=temp:degC x=gx:rad/s y=gy:rad/s z=gz:rad/s"


@dataclass(frozen=True)
class ColumnRole:
    """One ``ROLE=COLUMN[:UNIT]`` assignment (``unit`` None for grouping roles)."""

    role: str
    column: str
    unit: Unit | None

    def token(self) -> str:
        return f"{self.role}={self.column}" + (f":{self.unit.name}" if self.unit else "")


@dataclass(frozen=True)
class ColumnMap:
    """Roles → columns with units; at least temperature, one rate axis and time, or
    instead of time the nominal sample rate ``rate_hz`` of a log without time stamps."""

    roles: tuple[ColumnRole, ...]
    rate_hz: float | None = None
    """Nominal sample rate (Hz) of a log without time stamps: time = row index / rate."""

    def __post_init__(self) -> None:
        have = [r.role for r in self.roles]
        dupes = sorted({r for r in have if have.count(r) > 1})
        if dupes:
            raise ConfigError(f"--columns: role(s) {dupes} given more than once")
        if self.rate_hz is not None:
            if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
                raise ConfigError(f"--rate-hz {self.rate_hz:g}: expected a sample rate > 0 Hz")
            if "time" in have:
                raise ConfigError(
                    f"--rate-hz {self.rate_hz:g} with a time column "
                    f"({self.column_of('time')!r}): give one or the other (--rate-hz is for "
                    "logs without time stamps)")
        required = ("temperature",) if self.rate_hz is not None else ("time", "temperature")
        missing = [r for r in required if r not in have]
        if not any(r in have for r in RATE_ROLES):
            missing.append("x|y|z")
        if missing:
            raise ConfigError(f"--columns: missing role(s) {missing} (given: "
                              f"{' '.join(r.token() for r in self.roles)}); e.g. "
                              f"--columns {EXAMPLE_COLUMNS}")

    def get(self, role: str) -> ColumnRole | None:
        return next((r for r in self.roles if r.role == role), None)

    def column_of(self, role: str) -> str:
        """The column of ``role`` (KeyError when the map has none)."""
        found = self.get(role)
        if found is None:
            raise KeyError(role)
        return found.column

    def tokens(self) -> str:
        """The map as ``--columns`` would take it (for provenance metadata)."""
        return " ".join(r.token() for r in self.roles)


def parse_columns(tokens: Sequence[str], *, rate_hz: float | None = None) -> ColumnMap:
    """Parse ``--columns`` tokens (see the module docstring); ConfigError names the token.
    ``rate_hz``: the nominal sample rate of a log without time stamps (no ``time``)."""
    roles = []
    for token in tokens:
        role, eq, rest = token.partition("=")
        role = role.strip()
        if not eq or not rest:
            hint = "" if eq else " (an input file? put input files before --columns)"
            raise ConfigError(f"--columns {token!r}: expected ROLE=COLUMN[:UNIT]{hint}, "
                              f"e.g. --columns {EXAMPLE_COLUMNS}")
        if role in GROUP_ROLES:
            roles.append(ColumnRole(role, rest, None))
            continue
        if role not in MEASURED_ROLES:
            raise ConfigError(f"--columns {token!r}: unknown role {role!r}; roles: "
                              f"{', '.join([*MEASURED_ROLES, *GROUP_ROLES])}")
        kind = MEASURED_ROLES[role]
        column, colon, unit_name = rest.rpartition(":")
        if not colon or not column:
            raise ConfigError(f"--columns {token!r}: role {role!r} needs a unit "
                              f"(COLUMN:UNIT), one of {unit_names(kind)}")
        unit = UNITS[kind].get(unit_name)
        if unit is None:
            raise ConfigError(f"--columns {token!r}: unknown {kind} unit {unit_name!r}; "
                              f"known: {unit_names(kind)}")
        roles.append(ColumnRole(role, column, unit))
    return ColumnMap(tuple(roles), rate_hz=rate_hz)


@dataclass(frozen=True)
class InputSpec:
    """How to read the user's inputs (the CLI's input options).

    ``format``: ``"auto"`` (decided per file, see :func:`gyrotherm.readers.read_runs`)
    or a name from :data:`gyrotherm.readers.FORMATS`. ``columns``: the column map
    of delimited text, None = recognise the header. ``delimiter``: None = detect
    (``,`` ``;`` tab, else whitespace), ``" "`` = any whitespace. ``dbc`` and
    ``signals``: DBC file and signal map of candump logs (None = the shipped
    DBC / the default map). ``imu_topic``, ``temperature_topic``: rosbag2/MCAP
    topics (None = auto). ``bad_lines``: what a damaged line of delimited text does,
    ``"error"`` or ``"skip"`` (dropped and listed in the run's metadata).
    """

    format: str = "auto"
    columns: ColumnMap | None = None
    delimiter: str | None = None
    dbc: Path | None = None
    signals: SignalMap | None = None
    imu_topic: str | None = None
    temperature_topic: str | None = None
    bad_lines: str = "error"


def load_signal_map(path: str | os.PathLike[str]) -> SignalMap:
    """The signal map in TOML file ``path``: its ``[can.signals]`` table (so a daemon
    config works as is; one with a ``[can]`` table but no ``[can.signals]`` means the
    default map, as for the daemon), else its ``[signals]`` table, else its top-level
    keys; keys as :meth:`SignalMap.from_dict`. ConfigError names the file."""
    import tomllib

    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read signal map: {exc.strerror}") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: not a TOML file: {exc}") from exc
    table: object = data
    where = str(p)
    can = data.get("can")
    if isinstance(can, Mapping):
        if "signals" not in can:  # a daemon config without the table: the default map
            return SignalMap.default()
        table, where = can["signals"], f"{p}: [can.signals]"
    elif "signals" in data:
        table, where = data["signals"], f"{p}: [signals]"
    if not isinstance(table, Mapping):
        raise ConfigError(f"{where}: expected a table of SignalMap keys")
    return SignalMap.from_dict(table, source=where)
