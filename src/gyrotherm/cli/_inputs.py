"""The input options shared by ``fit``, ``evaluate``, ``diagnose`` and ``import``.

:func:`add_input_options` adds them to a parser once; :func:`load_inputs` reads
every input path with :func:`gyrotherm.readers.read_runs` (several runs per file
when a log holds several devices or ``--columns`` names a ``device``/``run``
column).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import Run
from gyrotherm.readers import BAD_LINES, FORMATS, InputSpec, load_signal_map, parse_columns

_DELIMITERS = {"comma": ",", "semicolon": ";", "tab": "\t", "whitespace": " "}


def add_input_options(parser: argparse.ArgumentParser) -> None:
    """``--format``, ``--columns``, ``--delimiter``, ``--dbc``, ``--signals``,
    ``--imu-topic``, ``--temperature-topic`` (see docs/inputs.md)."""
    g = parser.add_argument_group(
        "input (see docs/inputs.md)",
        "Inputs are gyrotherm run files, delimited text (CSV, TSV, ';'), candump -l logs, "
        "PX4 .ulg, ArduPilot .bin, rosbag2/MCAP; the format is told from the name and "
        "content. Put input files before --columns (it takes several values).")
    g.add_argument("--format", choices=FORMATS, default="auto",
                   help="read every input as this format (default auto)")
    g.add_argument("--columns", nargs="+", action="extend", metavar="ROLE=COL:UNIT",
                   help="column map of delimited text, e.g. time=timestamp:us "
                   "temperature=temp:degC x=gx:rad/s y=gy:rad/s z=gz:rad/s; roles time, "
                   "temperature, x, y, z, accel_x/y/z, device, run (default: recognise "
                   "run-file and PX4 ulog2csv sensor_gyro headers)")
    g.add_argument("--delimiter", choices=list(_DELIMITERS),
                   help="delimiter of delimited text (default: detected from the header)")
    g.add_argument("--rate-hz", type=float, metavar="HZ",
                   help="nominal sample rate of delimited text without time stamps (a "
                   "serial capture): time = row index / HZ, recorded as nominal; no time "
                   "column then (default: a time column)")
    g.add_argument("--bad-lines", choices=BAD_LINES,
                   help="a damaged line of delimited text (wrong field count, a mapped cell "
                   "not a finite number): stop with an error naming it, or skip it (each "
                   "run's metadata lists the lines dropped and why) (default error)")
    g.add_argument("--dbc", metavar="FILE",
                   help="DBC of candump logs (default: the shipped gyro.dbc)")
    g.add_argument("--signals", metavar="FILE.toml",
                   help="signal map of candump logs: a TOML file with the daemon's "
                   "[can.signals] table (a daemon config works) (default: the shipped map)")
    g.add_argument("--imu-topic", metavar="TOPIC",
                   help="rosbag2/MCAP sensor_msgs/msg/Imu topic (default: auto)")
    g.add_argument("--temperature-topic", metavar="TOPIC",
                   help="rosbag2/MCAP temperature topic (default: auto)")
    g.add_argument("--device", action="append", metavar="ID",
                   help="use only the runs of this device id, repeatable (PX4 device_id, "
                   "ArduPilot IMU[<n>], a CSV's device column; `gyrotherm import` lists "
                   "them) (default: every device)")


def spec_from_args(args: argparse.Namespace) -> InputSpec:
    """The :class:`InputSpec` of parsed input options (ConfigError on a bad value)."""
    columns = getattr(args, "columns", None)
    delimiter = getattr(args, "delimiter", None)
    dbc = getattr(args, "dbc", None)
    signals = getattr(args, "signals", None)
    rate_hz = getattr(args, "rate_hz", None)
    if rate_hz is not None and not columns:
        raise ConfigError(f"--rate-hz {rate_hz:g} needs --columns (the temperature and rate "
                          "columns of the log without time stamps, e.g. --columns "
                          "temperature=1:degC x=5:dps)")
    return InputSpec(
        format=getattr(args, "format", "auto"),
        columns=parse_columns(columns, rate_hz=rate_hz) if columns else None,
        delimiter=_DELIMITERS[delimiter] if delimiter else None,
        dbc=Path(dbc) if dbc else None,
        signals=load_signal_map(signals) if signals else None,
        imu_topic=getattr(args, "imu_topic", None),
        temperature_topic=getattr(args, "temperature_topic", None),
        bad_lines=getattr(args, "bad_lines", None) or "error",
    )


_OPTION_KEYS = ("format", "columns", "delimiter", "dbc", "signals", "imu_topic",
                "temperature_topic", "rate_hz", "bad_lines")


def recorded_options(args: argparse.Namespace) -> dict[str, object]:
    """The input options given (not left at their default), as a calibration's
    provenance records them (``input_options``), files as absolute paths: what
    ``gyrotherm export`` needs to read the fitting runs again."""
    out: dict[str, object] = {}
    for key in _OPTION_KEYS:
        value = getattr(args, key, None)
        if value is None or (key == "format" and value == "auto"):
            continue
        out[key] = str(Path(value).resolve()) if key in ("dbc", "signals") else value
    return out


def with_recorded_options(args: argparse.Namespace,
                          recorded: object) -> argparse.Namespace:
    """``args`` with the input options a calibration recorded filled in where the
    command line gave none (the command line wins)."""
    if not isinstance(recorded, dict) or any(
            getattr(args, k, None) not in (None, "auto") for k in _OPTION_KEYS):
        return args
    merged = argparse.Namespace(**vars(args))
    for key in _OPTION_KEYS:
        if key in recorded:
            setattr(merged, key, recorded[key])
    return merged


def load_inputs(args: argparse.Namespace, paths: list[str] | None = None) -> list[Run]:
    """Every run in ``paths`` (default ``args.runs``), read as the input options say,
    with a progress line unless ``args.quiet``."""
    from gyrotherm.cli._common import load_runs
    from gyrotherm.cli._identity import select_devices

    runs = load_runs(list(args.runs if paths is None else paths),
                     quiet=bool(getattr(args, "quiet", False)), spec=spec_from_args(args))
    return select_devices(runs, getattr(args, "device", None))
