"""Recognising a delimited text file's columns without ``--columns``.

Only headers whose units are certain are recognised:

* the run-file columns (``time_s``, ``temperature_c``, ``rate_<axis>_dps``) of a
  file without the ``# gyrotherm-run: 1`` line;
* a PX4 ``ulog2csv`` export of ``sensor_gyro`` (pyulog writes
  ``<log>_sensor_gyro_<instance>.csv`` with the header ``timestamp,
  timestamp_sample,device_id,x,y,z,temperature,...``): time from
  ``timestamp_sample`` (else ``timestamp``) in µs, rates in rad/s, temperature
  in °C, one run per ``device_id``. ``sensor_accel`` exports have the same
  header, so the file name must say ``sensor_gyro``.

Anything else (``timestamp,temp,gx,gy,gz`` says nothing of its units) needs
``--columns``; :func:`explain` writes the error, with an example line built
from the header.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

from gyrotherm.readers._spec import ColumnMap, parse_columns
from gyrotherm.readers._units import Kind

_SHOWN: dict[Kind, tuple[str, ...]] = {
    "time": ("s", "ms", "us", "ns"), "temperature": ("degC", "K", "mdegC"),
    "rate": ("dps", "rad/s", "mdps", "mrad/s"), "accel": ("m/s2", "g")}
_PX4_GYRO = {"timestamp", "device_id", "x", "y", "z", "temperature"}


def recognise(header: Sequence[str], stem: str) -> tuple[ColumnMap, str] | None:
    """The column map and a schema name for a known header, else None."""
    names = set(header)
    rates = [a for a in "xyz" if f"rate_{a}_dps" in names]
    if {"time_s", "temperature_c"} <= names and rates:
        tokens = ["time=time_s:s", "temperature=temperature_c:degC",
                  *(f"{a}=rate_{a}_dps:dps" for a in rates)]
        return parse_columns(tokens), "run-file columns"
    if _PX4_GYRO <= names and "sensor_gyro" in stem:
        time = "timestamp_sample" if "timestamp_sample" in names else "timestamp"
        tokens = [f"time={time}:us", "temperature=temperature:degC", "x=x:rad/s",
                  "y=y:rad/s", "z=z:rad/s", "device=device_id"]
        return parse_columns(tokens), "px4-ulog2csv sensor_gyro"
    return None


def _words(name: str) -> list[str]:
    return [w for w in re.split(r"[^a-z0-9]+", name.lower()) if w]


def _guess(header: Sequence[str], test: Callable[[list[str]], bool]) -> str | None:
    return next((h for h in header if test(_words(h))), None)


def _rate_test(axis: str) -> Callable[[list[str]], bool]:
    names = (axis, f"g{axis}", f"gyr{axis}", f"gyro{axis}", f"w{axis}", f"rate{axis}")

    def test(words: list[str]) -> bool:
        return not any(w.startswith("acc") for w in words) and any(w in names for w in words)

    return test


def example_columns(header: Sequence[str]) -> str:
    """A ``--columns`` line for ``header``: likely columns, the units to choose from."""
    def units(kind: Kind) -> str:
        return "<" + "|".join(_SHOWN[kind]) + ">"

    time = _guess(header, lambda w: bool(w) and (w[0] in ("t", "time", "timestamp")
                                                 or "time" in w or "timestamp" in w))
    temp = _guess(header, lambda w: any(x.startswith("temp") for x in w))
    parts = [f"time={time or '<column>'}:{units('time')}",
             f"temperature={temp or '<column>'}:{units('temperature')}"]
    for axis in "xyz":
        col = _guess(header, _rate_test(axis))
        parts.append(f"{axis}={col or '<column>'}:{units('rate')}")
    return "--columns " + " ".join(parts)
