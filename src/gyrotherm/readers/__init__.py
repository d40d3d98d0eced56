"""Readers of the user's own data: run files, delimited text with a column map,
candump logs with a user DBC, and (in their own modules) PX4 ULog, ArduPilot
DataFlash and rosbag2/MCAP logs. :func:`read_runs` picks one per file.

Every reader returns :class:`gyrotherm.codecs.Run` objects in the project's units:
``time_s`` (s), ``temperature_c`` (°C), ``rates_dps`` (°/s), the accelerometer
(when the source has one) in ``Run.extra`` as ``accel_x_mps2`` … (m/s²); metadata
``format``, ``device_id`` and ``instance``, and for text the original unit of each
column (``unit_<role>``). See docs/inputs.md.
"""

from gyrotherm.readers._dispatch import FORMATS, detect_format, read_runs
from gyrotherm.readers._spec import (
    ColumnMap,
    ColumnRole,
    InputSpec,
    load_signal_map,
    parse_columns,
)
from gyrotherm.readers._text import read_text
from gyrotherm.readers._textscan import BAD_LINES
from gyrotherm.readers._units import PROJECT_UNIT, UNITS, Unit

__all__ = [
    "BAD_LINES",
    "FORMATS",
    "PROJECT_UNIT",
    "UNITS",
    "ColumnMap",
    "ColumnRole",
    "InputSpec",
    "Unit",
    "detect_format",
    "load_signal_map",
    "parse_columns",
    "read_runs",
    "read_text",
]
