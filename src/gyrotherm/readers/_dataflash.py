"""ArduPilot DataFlash (``.bin``) reader, via pymavlink's ``DFReader_binary``.

One run per IMU instance, from the ``IMU`` message (ArduPilot
``AP_InertialSensor`` log structure, units from its ``FMTU``)::

    IMU  QBffffffIIfBBHH  TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz

* ``TimeUS`` (µs since boot; the time the sample was logged) → ``time_s``;
* ``I`` → instance (metadata ``device_id`` ``IMU[<I>]``);
* ``GyrX/Y/Z`` (rad/s) → ``rates_dps`` (× 180/π);
* ``T`` (°C) → ``temperature_c``;
* ``AccX/Y/Z`` (m/s²) → ``Run.extra`` ``accel_<axis>_mps2``.

Logs from before the ``I`` column (ArduPilot ≤ 3.x) log instances as separate
messages ``IMU``, ``IMU2``, ``IMU3`` with the temperature in ``Temp`` (and
``TimeMS`` in ms in the oldest): read the same way, instance from the name. A
log cut short is read up to its last whole message (pymavlink drops the partial
one; the reader does not report it).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._common import DEG_PER_RAD, S_PER_US, make_run, sha256_of

MESSAGES = ("IMU", "IMU2", "IMU3")
_GYRO = ("GyrX", "GyrY", "GyrZ")
_ACCEL = ("AccX", "AccY", "AccZ")


def _open(path: Path) -> Any:
    try:
        from pymavlink.DFReader import DFReader_binary
    except ModuleNotFoundError as exc:  # pragma: no cover  (a runtime dependency)
        raise RunFileError(f"{path}: reading DataFlash needs pymavlink: pip install pymavlink"
                           ) from exc
    try:
        return DFReader_binary(str(path))
    except Exception as exc:  # empty file (mmap), OSError, struct.error ...
        raise RunFileError(f"{path}: not a readable ArduPilot DataFlash log: {exc}") from exc


def _columns(fmt: Any) -> list[str]:
    return list(fmt.columns)


def read_dataflash(path: str | os.PathLike[str]) -> list[Run]:
    """Every IMU instance in DataFlash log ``path`` as a :class:`Run`, by instance.

    Raises :class:`RunFileError` naming the file, the message and what is missing.
    """
    p = Path(path)
    log = _open(p)
    rows: dict[tuple[str, int], list[tuple[float, ...]]] = {}
    layout: dict[str, tuple[str, str]] = {}  # message → (time column, temperature column)
    try:
        while (m := log.recv_match(type=list(MESSAGES))) is not None:
            name = m.get_type()
            if name not in layout:
                layout[name] = _layout(p, name, _columns(m.fmt))
            time_col, temp_col = layout[name]
            inst = int(m.I) if name == "IMU" and "I" in m.fmt.columns else MESSAGES.index(name)
            rows.setdefault((name, inst), []).append(
                (float(getattr(m, time_col)), float(getattr(m, temp_col)),
                 *(float(getattr(m, c)) for c in (*_GYRO, *_ACCEL))))
    except RunFileError:
        raise
    except Exception as exc:
        raise RunFileError(f"{p}: DataFlash log unreadable at byte {log.offset}: {exc}") from exc
    if not rows:
        seen = sorted(f.name for f in log.formats.values())
        raise RunFileError(f"{p}: no IMU message (of {list(MESSAGES)}) in the log; message "
                           f"formats defined: {seen or 'none (not a DataFlash log?)'}")
    sha = sha256_of(p)
    runs = []
    for (name, inst), values in sorted(rows.items(), key=lambda kv: kv[0][1]):
        a = np.asarray(values, dtype=np.float64)
        time_col, temp_col = layout[name]
        scale = 1e-3 if time_col == "TimeMS" else S_PER_US
        meta = {
            "format": "ardupilot-dataflash",
            "device_id": f"IMU[{inst}]",
            "instance": str(inst),
            "message": name,
            "unit_time": "ms" if time_col == "TimeMS" else "us",
            "unit_temperature": "degC",
            "unit_rate": "rad/s",
            "unit_accel": "m/s2",
        }
        runs.append(make_run(
            path=p, device=f"IMU[{inst}]", where=f"message {name!r} instance {inst}",
            time_s=a[:, 0] * scale, temperature_c=a[:, 1],
            rates={ax: a[:, 2 + k] for k, ax in enumerate("xyz")}, rate_to_dps=DEG_PER_RAD,
            accel_mps2={ax: a[:, 5 + k] for k, ax in enumerate("xyz")},
            metadata=meta, sha256=sha))
    return runs


def _layout(path: Path, name: str, columns: list[str]) -> tuple[str, str]:
    time_col = next((c for c in ("TimeUS", "TimeMS") if c in columns), None)
    temp_col = next((c for c in ("T", "Temp") if c in columns), None)
    missing = [c for c in _GYRO + _ACCEL if c not in columns]
    if time_col is None:
        missing.insert(0, "TimeUS")
    if temp_col is None:
        missing.append("T (temperature, ArduPilot ≥ 3.4)")
    if missing or time_col is None or temp_col is None:
        raise RunFileError(f"{path}: message {name!r}: missing column(s) {missing} "
                           f"(its columns: {columns})")
    return time_col, temp_col
