"""PX4 ULog (``.ulg``) reader, via pyulog.

One run per ``sensor_gyro`` instance (ULog ``multi_id``), in ascending instance
order. Fields used (PX4 ``msg/SensorGyro.msg``):

* ``timestamp_sample`` (µs since boot, the sample's own time; ``timestamp``,
  the publication time, when the log has no ``timestamp_sample``) → ``time_s``;
* ``x``, ``y``, ``z`` (rad/s) → ``rates_dps`` (× 180/π);
* ``temperature`` (°C) → ``temperature_c``; a gyro whose temperature is NaN
  throughout is an error (PX4 logs NaN for sensors without one);
* ``device_id`` → metadata ``device_id`` (and ``sensor_id``) as decimal, with the
  decoded ``DeviceStructure`` (bus type, bus, address, devtype) in ``device``;
* the vehicle: metadata ``vehicle_id`` = ``px4-uuid:<sys_uuid>`` (the flight controller's
  unique id from the log's info messages; empty without one), ``board`` = ``ver_hw``.

``sensor_accel`` with the same instance, when logged, is interpolated onto the
gyro's time stamps (linear, no extrapolation) into ``Run.extra``
``accel_<axis>_mps2`` (m/s²); metadata ``accel`` says ``sensor_accel <i>`` or
``none``. The arming state, from ``vehicle_status.arming_state`` (armed = 2,
``ARMING_STATE_ARMED`` in PX4's ``msg/VehicleStatus.msg``, every version), else
``actuator_armed.armed``, is held onto the gyro's rows into ``Run.extra["armed"]`` (1/0;
rows before the first message take its value); metadata ``armed`` names the source or
``none``. Logs pyulog flags as corrupt, or that end inside a message (a log cut
short: metadata ``bytes_cut_at_end``), are still read up to the damage (metadata
``file_corruption: true``). An instance that cannot be read (NaN temperature
throughout) is skipped when others can (metadata ``instances_skipped``).
"""

from __future__ import annotations

import contextlib
import io
import mmap
import os
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._common import (
    DEG_PER_RAD,
    FALLBACK_KEY,
    S_PER_US,
    FloatArray,
    each_instance,
    interpolate,
    make_run,
    sha256_of,
    sort_unique,
    state_at,
)

GYRO_TOPIC = "sensor_gyro"
ACCEL_TOPIC = "sensor_accel"
STATUS_TOPIC = "vehicle_status"
ARMED_TOPIC = "actuator_armed"
ARMING_STATE_ARMED = 2
TOPICS = [GYRO_TOPIC, ACCEL_TOPIC, STATUS_TOPIC, ARMED_TOPIC]
FIELDS = {GYRO_TOPIC: ("timestamp_sample|timestamp", "device_id", "x", "y", "z", "temperature"),
          ACCEL_TOPIC: ("timestamp_sample|timestamp", "x", "y", "z"),
          STATUS_TOPIC: ("timestamp", "arming_state"), ARMED_TOPIC: ("timestamp", "armed")}
"""What the reader reads of each topic (the fast path decodes only those)."""
"""``vehicle_status.arming_state`` of an armed vehicle (PX4 ``msg/VehicleStatus.msg``)."""
_BUS_TYPES = {0: "unknown", 1: "I2C", 2: "SPI", 3: "UAVCAN", 4: "simulation",
              5: "serial", 6: "MAVLink"}


def decode_device_id(device_id: int) -> str:
    """PX4's ``DeviceStructure`` (bus_type:3, bus:5, address:8, devtype:8, from the
    least significant bit) as text, e.g. 263178 → ``SPI bus 1 address 0x04 devtype 0x04``."""
    bus_type = device_id & 0x7
    bus = (device_id >> 3) & 0x1F
    address = (device_id >> 8) & 0xFF
    devtype = (device_id >> 16) & 0xFF
    kind = _BUS_TYPES.get(bus_type, f"bus type {bus_type}")
    return f"{kind} bus {bus} address 0x{address:02x} devtype 0x{devtype:02x}"


def _load(path: Path) -> tuple[Any, str]:
    """pyulog's ULog of ``path`` and what pyulog printed about it ("" or "; pyulog: ...")."""
    try:
        from pyulog import ULog
    except ModuleNotFoundError as exc:  # pragma: no cover  (a runtime dependency)
        raise RunFileError(f"{path}: reading PX4 ULog needs pyulog: pip install pyulog") from exc
    said = io.StringIO()  # pyulog prints what it finds wrong on stdout: kept, not shown
    try:
        with contextlib.redirect_stdout(said):
            ulog = ULog(str(path), TOPICS)
    except Exception as exc:  # pyulog raises ULogException, struct.error, IndexError ...
        raise RunFileError(f"{path}: not a readable PX4 ULog file: {exc}"
                           f"{_pyulog_said(said.getvalue())}") from exc
    return ulog, _pyulog_said(said.getvalue())


def _load_fast(path: Path) -> tuple[Any, str, int | None, str]:
    """The topics decoded by numpy, else by pyulog: (ulog, what pyulog said, bytes cut
    at the end when known, why pyulog read it or "")."""
    from gyrotherm.readers._fast_common import Fallback
    from gyrotherm.readers._fast_ulog import load

    try:
        fast = load(path, TOPICS, fields=FIELDS)
    except Fallback as exc:
        return *_load(path), None, f"read by pyulog: {exc}"
    return fast, "", fast.bytes_cut_at_end, ""


def _pyulog_said(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return f"; pyulog: {'; '.join(lines)}" if lines else ""


def read_ulog(path: str | os.PathLike[str], *, fast: bool = True) -> list[Run]:
    """Every ``sensor_gyro`` instance in ULog file ``path`` as a :class:`Run`.

    The data messages are decoded by numpy (:mod:`._fast_ulog`); what that does not
    cover is read by pyulog, with the reason in metadata ``fast_path_fallback``
    (``fast=False``: pyulog always, the reference the fast path is tested against).
    Raises :class:`RunFileError` naming the file, the topic and what is missing.
    """
    p = Path(path)
    ulog, said, cut_bytes, fallback = _load_fast(p) if fast else (*_load(p), None, "")
    gyros = sorted((d for d in ulog.data_list if d.name == GYRO_TOPIC), key=lambda d: d.multi_id)
    if not gyros and (ulog.file_corruption or said):
        raise RunFileError(
            f"{p}: a damaged or cut ULog ({p.stat().st_size} bytes{said}"
            f"): no {GYRO_TOPIC!r} data before the damage; give the complete file")
    if not gyros:
        imu = [d for d in ulog.data_list if d.name in (GYRO_TOPIC, ACCEL_TOPIC)]
        logged = sorted({d.name for d in imu})
        raise RunFileError(
            f"{p}: no {GYRO_TOPIC!r} topic logged (this log has {len(imu)} "
            f"topics among {GYRO_TOPIC!r}/{ACCEL_TOPIC!r}: {logged}); enable it in the "
            "PX4 logger (SDLOG_PROFILE 'thermal calibration' or 'sensor comparison')")
    accels = {d.multi_id: d for d in ulog.data_list if d.name == ACCEL_TOPIC}
    sha = sha256_of(p)
    corrupt = bool(getattr(ulog, "file_corruption", False))
    if cut_bytes is None:
        cut_bytes = bytes_cut_at_end(p)
    armed = arming_state(ulog)
    info = getattr(ulog, "msg_info_dict", {}) or {}
    uuid = str(info.get("sys_uuid", "") or "")
    vehicle = {"vehicle_id": f"px4-uuid:{uuid}" if uuid else "",
               "board": str(info.get("ver_hw", "") or ""),
               **({FALLBACK_KEY: fallback} if fallback else {})}
    return each_instance(p, [(f"topic {GYRO_TOPIC!r} instance {g.multi_id}",
                              partial(_run, p, g, accels.get(g.multi_id), sha, corrupt,
                                      cut_bytes, armed, vehicle))
                             for g in gyros])


def arming_state(ulog: Any) -> tuple[FloatArray, FloatArray, str] | None:
    """(time s, 1 armed / 0 not, source) from ``vehicle_status.arming_state``, else
    ``actuator_armed.armed``; None when the log has neither."""
    for topic, field, armed in ((STATUS_TOPIC, "arming_state", ARMING_STATE_ARMED),
                                (ARMED_TOPIC, "armed", 1)):
        d = next((d for d in ulog.data_list if d.name == topic and field in d.data), None)
        if d is None or len(d.data[field]) == 0:
            continue
        t = np.asarray(d.data["timestamp"], dtype=np.float64) * S_PER_US
        rows, _, _ = sort_unique(t)
        state = (np.asarray(d.data[field])[rows] == armed).astype(np.float64)
        return t[rows], state, f"{topic}.{field}"
    return None


def bytes_cut_at_end(path: Path) -> int:
    """Bytes of the message the file ends inside, 0 for a log that ends on a message
    boundary. ULog messages are ``uint16 size, uint8 type, payload`` after the 16-byte
    header, walked from the start (mapped, not read into memory); a log cut while
    being written, or copied short, ends inside one."""
    with path.open("rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as data:
        pos, end, last = _HEADER_BYTES, len(data), _HEADER_BYTES
        while pos + 3 <= end:
            last = pos
            pos += 3 + int.from_bytes(data[pos:pos + 2], "little")
    if pos == end:
        return 0
    return end - last if pos > end else end - pos


_HEADER_BYTES = 16


def _time_s(data: dict[str, Any]) -> tuple[FloatArray, str]:
    key = "timestamp_sample" if "timestamp_sample" in data else "timestamp"
    return np.asarray(data[key], dtype=np.float64) * S_PER_US, key


def _run(path: Path, gyro: Any, accel: Any, sha: str, corrupt: bool, cut_bytes: int,
         armed: tuple[FloatArray, FloatArray, str] | None,
         vehicle: dict[str, str] | None = None) -> Run:
    where = f"topic {GYRO_TOPIC!r} instance {gyro.multi_id}"
    data: dict[str, Any] = gyro.data
    need = ("x", "y", "z", "temperature", "device_id")
    missing = [f for f in need if f not in data]
    if missing:
        raise RunFileError(f"{path}: {where}: missing field(s) {missing} "
                           f"(fields: {sorted(data)})")
    t, time_field = _time_s(data)
    dev = np.asarray(data["device_id"], dtype=np.int64)
    one = len(dev) > 0 and bool(np.all(dev == dev[0]))  # the usual: one device throughout
    ids = dev[:1] if one else np.unique(dev)
    device_id = int(ids[-1]) if len(ids) else 0
    accel_mps2: dict[str, FloatArray] | None = None
    accel_label = "none"
    if accel is not None and all(a in accel.data for a in "xyz"):
        ta, _ = _time_s(accel.data)
        rows, _, _ = sort_unique(ta)
        accel_mps2 = {a: interpolate(ta[rows], np.asarray(accel.data[a], np.float64)[rows], t)
                      for a in "xyz"}
        accel_label = f"{ACCEL_TOPIC} {accel.multi_id}"
    meta = {
        "format": "px4-ulog",
        "device_id": str(device_id),
        "sensor_id": str(device_id),
        **(vehicle or {"vehicle_id": "", "board": ""}),
        "device": decode_device_id(device_id),
        "instance": str(gyro.multi_id),
        "topic": GYRO_TOPIC,
        "time_field": time_field,
        "unit_time": "us",
        "unit_temperature": "degC",
        "unit_rate": "rad/s",
        "unit_accel": "m/s2",
        "accel": accel_label,
        "armed": armed[2] if armed is not None else "none",
        "file_corruption": "true" if corrupt or cut_bytes else "false",
        "bytes_cut_at_end": str(cut_bytes),
    }
    if len(ids) > 1:
        meta["device_ids_seen"] = ",".join(str(int(i)) for i in ids)
    return make_run(
        path=path, device=f"{GYRO_TOPIC}{gyro.multi_id}", where=where, time_s=t,
        temperature_c=np.asarray(data["temperature"], dtype=np.float64),
        rates={a: np.asarray(data[a], dtype=np.float64) for a in "xyz"},
        rate_to_dps=DEG_PER_RAD, accel_mps2=accel_mps2, metadata=meta, sha256=sha,
        armed=None if armed is None else state_at(armed[0], armed[1], t, armed[1][0]))
