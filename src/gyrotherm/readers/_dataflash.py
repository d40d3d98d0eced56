"""ArduPilot DataFlash (``.bin``) reader, via pymavlink's ``DFReader_binary``.

One run per IMU instance, from the ``IMU`` message (ArduPilot
``AP_InertialSensor`` log structure, units from its ``FMTU``)::

    IMU  QBffffffIIfBBHH  TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz

* ``TimeUS`` (µs since boot; the time the sample was logged) → ``time_s``;
* ``I`` → instance (metadata ``device_id`` ``IMU[<I>]``);
* ``GyrX/Y/Z`` (rad/s) → ``rates_dps`` (× 180/π);
* ``T`` (°C) → ``temperature_c``;
* ``AccX/Y/Z`` (m/s²) → ``Run.extra`` ``accel_<axis>_mps2``;
* the IMU's identity: metadata ``sensor_id`` = ``INS_GYR<n>_ID`` from the log's ``PARM``
  messages (``INS_GYR_ID`` for instance 0, ``INS_GYR2_ID`` … ; the device id of its
  bus, address and type, the same on every board of a model), ``vehicle_id`` =
  ``ardupilot-uid:<96-bit MCU id>`` from the boot message ChibiOS boards log
  (``MSG`` "omnibusf4pro 0034005A 4E4E5005 20363553": board name and unique id), ``board``
  the board name; empty when the log has none (``SYSID_THISMAV`` is not used: it is 1
  on most vehicles);
* the frame and correction of the logged rates: metadata ``ahrs_orientation``
  (``AHRS_ORIENTATION``: the ``IMU`` message is in the body frame, rotated from the
  sensor's by the board orientation) and ``tcal_enable`` (``INS_TCAL<n>_ENABLE``: 1 means
  the logged rates are already corrected by the autopilot's thermal calibration); empty
  when the log does not say. ``fit`` and ``export`` refuse what they cannot undo
  (:mod:`gyrotherm.cli._identity`);
* the arming state → ``Run.extra["armed"]`` (1/0 per row; metadata ``armed`` names the
  source or ``none``): from ``ARM`` messages (``ArmState``, 1 armed) or, without them,
  ``EV`` events (``Id`` 10 ARMED, 11 DISARMED, ArduPilot's ``LogEvent``), each held until
  the next; rows before the first take the state it left (a transition).

Logs from before the ``I`` column (ArduPilot ≤ 3.x) log instances as separate
messages ``IMU``, ``IMU2``, ``IMU3`` with the temperature in ``Temp`` (and
``TimeMS`` in ms in the oldest): read the same way, instance from the name. A
log cut short is read up to its last whole message (metadata
``messages_cut_at_end`` counts the IMU messages lost, all instances).

pymavlink indexes the log (message offsets, ``FMT`` formats, its struct codes and
multipliers); the IMU messages' fields are then gathered with numpy in chunks,
not one Python object per message (200 k messages: 27 s → 4 s, of which the
decode is 0.2 s and pymavlink's indexing the rest).
"""

from __future__ import annotations

import os
import re
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._common import (
    DEG_PER_RAD,
    FALLBACK_KEY,
    S_PER_US,
    FloatArray,
    each_instance,
    make_run,
    sha256_of,
    sort_unique,
    state_at,
)
from gyrotherm.readers._fast_common import fields_at

MESSAGES = ("IMU", "IMU2", "IMU3")
_GYRO = ("GyrX", "GyrY", "GyrZ")
_ACCEL = ("AccX", "AccY", "AccZ")
EV_ARMED, EV_DISARMED = 10, 11
"""ArduPilot ``LogEvent`` ids of the ``EV`` message (AP_Logger)."""
Arming = tuple[FloatArray, FloatArray, str]


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


_NUMPY = {"b": "i1", "B": "u1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4", "q": "<i8",
          "Q": "<u8", "e": "<f2", "f": "<f4", "d": "<f8"}



def _dtype(path: Path, name: str, msg_struct: str) -> np.dtype[np.void]:
    """The numpy record of a DataFlash message body from pymavlink's struct string."""
    fields: list[tuple[str, str]] = []
    for count, code in re.findall(r"(\d*)([a-zA-Z])", msg_struct.lstrip("<")):
        if code == "s":
            fields.append((f"f{len(fields)}", f"S{count or 1}"))
        elif code in _NUMPY and not count:
            fields.append((f"f{len(fields)}", _NUMPY[code]))
        else:
            raise RunFileError(f"{path}: message {name!r}: unsupported field {count}{code!r}")
    return np.dtype(fields)


def _decode(path: Path, log: Any, name: str, listed: NDArray[np.int64]
            ) -> tuple[dict[str, FloatArray], int]:
    """Every ``name`` message's columns (multipliers applied), from pymavlink's index
    of the log (``listed``: the messages' offsets; ``formats``), and how many were cut
    by the end of the file (left out)."""
    columns: list[str] = list(log.formats[log.name_to_id[name]].columns)
    time_col, temp_col = _layout(path, name, columns)
    wanted = [time_col, temp_col, *_GYRO, *_ACCEL] + (["I"] if "I" in columns else [])
    return _gather(path, log, name, listed, wanted)


def _gather(path: Path, log: Any, name: str, listed: NDArray[np.int64], wanted: list[str]
            ) -> tuple[dict[str, FloatArray], int]:
    """Columns ``wanted`` of the ``name`` messages at offsets ``listed``, and how many
    were cut by the end of the file."""
    fmt = log.formats[log.name_to_id[name]]
    columns: list[str] = list(fmt.columns)
    offs = listed[listed + int(fmt.len) <= int(log.data_len)]
    dtype = _dtype(path, name, fmt.msg_struct)
    if dtype.itemsize != int(fmt.len) - 3:
        raise RunFileError(f"{path}: message {name!r}: FMT length {fmt.len} does not match "
                           f"its format {fmt.format!r}")
    buf = np.frombuffer(log.data_map, dtype=np.uint8)
    raw = fields_at(buf, offs + 3, dtype, tuple(f"f{columns.index(c)}" for c in wanted),
                    as_dtype=np.float64)
    out: dict[str, FloatArray] = {}
    for c in wanted:
        i = columns.index(c)
        mult = fmt.msg_mults[i]
        v = raw.pop(f"f{i}")
        if mult is not None:
            v *= mult
        out[c] = v
    return out, len(listed) - len(offs)


def read_dataflash(path: str | os.PathLike[str], *, fast: bool = True) -> list[Run]:
    """Every IMU instance in DataFlash log ``path`` as a :class:`Run`, by instance.

    The log is indexed by numpy (:mod:`._fast_dataflash`); what that does not cover
    is indexed by pymavlink, with the reason in metadata ``fast_path_fallback``
    (``fast=False``: pymavlink always, the reference the fast path is tested against).
    Raises :class:`RunFileError` naming the file, the message and what is missing.
    """
    p = Path(path)
    log, fallback = _open_fast(p) if fast else (_open(p), "")
    try:
        armed = arming_state(p, log)
        ident = identity(p, log)  # before _parts, which frees pymavlink's index
        parts, cut = _parts(p, log)
    finally:
        log.close()  # the mmap and the file handle
    sha = sha256_of(p)
    if fallback:
        ident = {**ident, FALLBACK_KEY: fallback}
    return each_instance(p, [(f"message {name!r} instance {inst}",
                              partial(_run, p, inst, name, cols, cut=cut, sha=sha, armed=armed,
                                      ident=ident))
                             for inst, name, cols in sorted(parts, key=lambda x: x[0])])


def _open_fast(path: Path) -> tuple[Any, str]:
    """The log indexed by numpy, else by pymavlink with the reason ("" when fast)."""
    from gyrotherm.readers._fast_dataflash import Fallback, open_fast

    try:
        return open_fast(path), ""
    except Fallback as exc:
        return _open(path), f"indexed by pymavlink: {exc}"


def arming_state(p: Path, log: Any) -> Arming | None:
    """(time s, 1 armed / 0 not, source) from the ``ARM`` messages, else the ``EV``
    events ARMED/DISARMED; None when the log has neither (or no time column in them)."""
    for name, field in (("ARM", "ArmState"), ("EV", "Id")):
        mtype = log.name_to_id.get(name)
        if mtype is None or not len(log.offsets[mtype]):
            continue
        columns = list(log.formats[mtype].columns)
        time_col = next((c for c in ("TimeUS", "TimeMS") if c in columns), None)
        if time_col is None or field not in columns:
            continue
        cols, _ = _gather(p, log, name, np.asarray(log.offsets[mtype], dtype=np.int64),
                          [time_col, field])
        t = cols[time_col] * (1e-3 if time_col == "TimeMS" else S_PER_US)
        v = cols[field]
        if name == "EV":
            keep = (v == EV_ARMED) | (v == EV_DISARMED)
            t, v = t[keep], (v[keep] == EV_ARMED).astype(np.float64)
        else:
            v = (v == 1).astype(np.float64)
        rows, _, _ = sort_unique(t)
        if len(rows):
            return t[rows], v[rows], f"{name}.{field}"
    return None


_UID = re.compile(r"^(?P<board>\S+) (?P<uid>[0-9A-F]{8} [0-9A-F]{8} [0-9A-F]{8})$")


def _records(path: Path, log: Any, name: str, fields: list[str]) -> list[tuple[Any, ...]]:
    """The ``fields`` of every ``name`` message (strings decoded), in log order."""
    mtype = log.name_to_id.get(name)
    if mtype is None or not len(log.offsets[mtype]):
        return []
    fmt = log.formats[mtype]
    columns = list(fmt.columns)
    if not all(f in columns for f in fields):
        return []
    dtype = _dtype(path, name, fmt.msg_struct)
    if dtype.itemsize != int(fmt.len) - 3:
        return []
    offs = np.asarray(log.offsets[mtype], dtype=np.int64)
    offs = offs[offs + int(fmt.len) <= int(log.data_len)]
    buf = np.frombuffer(log.data_map, dtype=np.uint8)
    rec = buf[offs[:, None] + np.arange(3, int(fmt.len), dtype=np.int64)].view(dtype)[:, 0]
    cols = [rec[f"f{columns.index(f)}"] for f in fields]
    return [tuple(v.split(b"\0", 1)[0].decode("ascii", "replace") if isinstance(v, bytes)
                  else float(v) for v in row) for row in zip(*cols, strict=True)]


def _int_text(value: str | None) -> str:
    return "" if value is None else str(int(float(value)))


def identity(p: Path, log: Any) -> dict[str, str]:
    """``INS_GYR*_ID`` parameters (the last value logged) and the board's unique id."""
    params = {name: value for name, value in _records(p, log, "PARM", ["Name", "Value"])}
    out = {f"sensor_id:{k}": str(int(v)) for k, v in params.items()
           if re.fullmatch(r"INS_GYR\d?_ID", k) and v}
    out.update({f"param:{k}": repr(float(v)) for k, v in params.items()
                if k == "AHRS_ORIENTATION" or re.fullmatch(r"INS_TCAL\d_ENABLE", k)})
    for (text,) in _records(p, log, "MSG", ["Message"]):
        m = _UID.match(text.strip())
        if m:
            out["vehicle_id"] = "ardupilot-uid:" + m["uid"].replace(" ", "")
            out["board"] = m["board"]
            break
    return out


def _run(p: Path, inst: int, name: str, cols: dict[str, FloatArray], *, cut: int,
         sha: str, armed: Arming | None, ident: dict[str, str] | None = None) -> Run:
    time_col = "TimeUS" if "TimeUS" in cols else "TimeMS"
    temp = cols["T"] if "T" in cols else cols["Temp"]
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
        "messages_cut_at_end": str(cut),
        "armed": armed[2] if armed is not None else "none",
        "vehicle_id": (ident or {}).get("vehicle_id", ""),
        "board": (ident or {}).get("board", ""),
        "sensor_id": (ident or {}).get(
            f"sensor_id:INS_GYR{'' if inst == 0 else inst + 1}_ID", ""),
        "ahrs_orientation": _int_text((ident or {}).get("param:AHRS_ORIENTATION")),
        "tcal_enable": _int_text((ident or {}).get(f"param:INS_TCAL{inst + 1}_ENABLE")),
    }
    if (ident or {}).get(FALLBACK_KEY):
        meta[FALLBACK_KEY] = (ident or {})[FALLBACK_KEY]
    t = cols[time_col] * scale
    return make_run(
        path=p, device=f"IMU[{inst}]", where=f"message {name!r} instance {inst}",
        time_s=t, temperature_c=temp,
        rates={ax: cols[c] for ax, c in zip("xyz", _GYRO, strict=True)},
        rate_to_dps=DEG_PER_RAD,
        accel_mps2={ax: cols[c] for ax, c in zip("xyz", _ACCEL, strict=True)},
        metadata=meta, sha256=sha,
        armed=None if armed is None else state_at(armed[0], armed[1], t, 1.0 - armed[1][0]))


def _parts(p: Path, log: Any) -> tuple[list[tuple[int, str, dict[str, FloatArray]]], int]:
    """(instance, message, columns) per IMU instance, and the messages cut at the end."""
    present = [m for m in MESSAGES if m in log.name_to_id and len(log.offsets[
        log.name_to_id[m]]) > 0]
    if not present:
        seen = sorted(f.name for f in log.formats.values())
        raise RunFileError(f"{p}: no IMU message (of {list(MESSAGES)}) in the log: the "
                           "autopilot did not log it (set the IMU bit of LOG_BITMASK and log "
                           f"again); message formats defined: "
                           f"{seen or 'none (not a DataFlash log?)'}")
    parts: list[tuple[int, str, dict[str, FloatArray]]] = []
    cut = 0
    offsets = {name: np.asarray(log.offsets[log.name_to_id[name]], dtype=np.int64)
               for name in present}
    log.offsets = None  # pymavlink's index: a Python int per message, 36 bytes each
    for name in present:
        cols, n_cut = _decode(p, log, name, offsets.pop(name))
        cut += n_cut
        if len(cols[_GYRO[0]]) == 0:  # every one of them cut by the end of the file
            continue
        if "I" not in cols:  # ArduPilot 3.x: the instance is in the message name
            parts.append((MESSAGES.index(name), name, cols))
            continue
        first = cols["I"][0]
        instances = np.array([int(first)]) if bool(np.all(cols["I"] == first)) else \
            np.unique(cols["I"]).astype(int)
        for inst in instances:  # one instance: its columns as decoded, not copied
            sel = slice(None) if len(instances) == 1 else cols["I"] == inst
            parts.append((int(inst), name, {c: v[sel] for c, v in cols.items()}))
    if not parts:
        raise RunFileError(f"{p}: every IMU message ({', '.join(present)}: {cut}) is cut "
                           "short by the end of the file: nothing to read")
    return parts, cut


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
