"""rosbag2 (``.db3``, MCAP storage, or the bag directory), plain ``.mcap`` and ROS 1
``.bag`` reader, via rosbags (ROS 2 CDR messages decoded with rosbags' ROS 2 Humble
type store: ``sensor_msgs`` Imu and Temperature are the same in every ROS 2
release; ROS 1 messages with its Noetic store, the types named as in ROS 2).

* IMU: every ``sensor_msgs/msg/Imu`` topic (or only ``imu_topic``); one run per
  topic and ``header.frame_id``. ``header.stamp`` (the sample's time, s since the
  epoch; float64 resolves ≈ 0.24 µs there) → ``time_s``, the bag's receive
  time when the stamp is zero (metadata ``time_field``); ``angular_velocity``
  (rad/s) → ``rates_dps`` (× 180/π; a message marking it absent,
  ``angular_velocity_covariance[0] == -1``, counts as a non-finite row);
  ``linear_acceleration`` (m/s²) → ``Run.extra`` ``accel_<axis>_mps2`` unless
  the message marks it absent (``linear_acceleration_covariance[0] == -1``).
* Temperature: a ``sensor_msgs/msg/Temperature`` topic (``temperature`` in °C,
  its ``header.stamp``). ``temperature_topic`` names it; without it the only
  such topic is taken, or, with several, the one in the IMU topic's namespace
  (``/imu0/data`` ↔ ``/imu0/temperature``); anything else is an error listing
  the candidates. Each IMU sample takes the latest temperature at or before
  its stamp (hold); samples before the first temperature are dropped
  (metadata ``rows_before_first_temperature``).
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import Run
from gyrotherm.readers._common import (
    DEG_PER_RAD,
    FALLBACK_KEY,
    S_PER_NS,
    hold_previous,
    make_run,
    sha256_of,
    sort_unique,
)
from gyrotherm.readers._magic import content_kind

IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"


def _namespace(topic: str) -> str:
    return topic.rsplit("/", 1)[0]


def _pick_temperature(path: Path, imu: str, temps: Sequence[str], chosen: str | None) -> str:
    if chosen is not None:
        if chosen not in temps:
            raise RunFileError(f"{path}: temperature topic {chosen!r} is not a {TEMPERATURE_TYPE}"
                               f" topic of the bag; candidates: {list(temps)}")
        return chosen
    if not temps:
        raise RunFileError(f"{path}: IMU topic {imu!r}: no {TEMPERATURE_TYPE} topic in the bag "
                           "(a gyro temperature is needed)")
    if len(temps) == 1:
        return temps[0]
    same_ns = [t for t in temps if _namespace(t) == _namespace(imu)]
    if len(same_ns) == 1:
        return same_ns[0]
    raise RunFileError(f"{path}: IMU topic {imu!r}: several {TEMPERATURE_TYPE} topics "
                       f"{list(temps)}; name one (temperature_topic / --temperature-topic)")


def _open(path: Path, *, ros1: bool) -> Any:
    try:
        from rosbags.rosbag1 import Reader as Reader1
        from rosbags.rosbag2 import Reader as Reader2
    except ModuleNotFoundError as exc:  # pragma: no cover  (a runtime dependency)
        raise RunFileError(f"{path}: reading rosbag2/MCAP needs rosbags: pip install rosbags"
                           ) from exc
    reader = Reader1(path) if ros1 else Reader2(path)
    reader.open()
    return reader


class _Rows:
    """IMU rows gathered a chunk at a time into numpy arrays: stamps (int64 ns, exact)
    and six floats (ω x y z rad/s, a x y z m/s²). A Python tuple per row costs ≈ 290
    bytes: 1 GB for a 1-hour 1 kHz bag; this costs 56 bytes a row."""

    CHUNK = 1 << 16

    def __init__(self) -> None:
        self._stamps: list[int] = []
        self._values: list[tuple[float, ...]] = []
        self._done_stamps: list[NDArray[np.int64]] = []
        self._done_values: list[NDArray[np.float64]] = []

    def append(self, stamp_ns: int, values: tuple[float, ...]) -> None:
        self._stamps.append(stamp_ns)
        self._values.append(values)
        if len(self._stamps) >= self.CHUNK:
            self._flush()

    def _flush(self) -> None:
        if self._stamps:
            self._done_stamps.append(np.asarray(self._stamps, dtype=np.int64))
            self._done_values.append(np.asarray(self._values, dtype=np.float64).reshape(-1, 6))
            self._stamps, self._values = [], []

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Stamps (ns) and the (n, 6) values, in arrival order."""
        self._flush()
        stamps = np.concatenate(self._done_stamps) if self._done_stamps else \
            np.zeros(0, dtype=np.int64)
        values = np.concatenate(self._done_values) if self._done_values else np.zeros((0, 6))
        self._done_stamps, self._done_values = [], []
        return stamps, values


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def read_rosbag(path: str | os.PathLike[str], *, imu_topic: str | None = None,
                temperature_topic: str | None = None, fast: bool = True) -> list[Run]:
    """One :class:`Run` per IMU topic and frame_id of the bag or MCAP file ``path``.

    An indexed ``.mcap`` file's messages are decoded by numpy (:mod:`._fast_mcap`,
    :mod:`._fast_cdr`); what that does not cover is decoded by rosbags with the
    reason in metadata ``fast_path_fallback``, as are rosbag2 directories, ``.db3``
    and ROS 1 bags (without a note: not in the fast path's scope). ``fast=False``:
    rosbags always, the reference the fast path is tested against.

    Raises :class:`RunFileError` naming the file, the topic and what is missing.
    """
    p = Path(path)
    ros1 = content_kind(p) == "ros1"
    kind = "ROS 1 bag" if ros1 else "rosbag2/MCAP file"
    try:
        reader = _open(p, ros1=ros1)
    except RunFileError:
        raise
    except Exception as exc:  # rosbags' ReaderError, FileNotFoundError, yaml/sqlite errors
        raise RunFileError(f"{p}: not a readable {kind}: {exc}"
                           + ("; a cut MCAP file can be salvaged with `mcap recover`"
                              if "magic" in str(exc).lower() and not ros1 else "")) from exc
    try:
        return _read(p, reader, imu_topic, temperature_topic, ros1=ros1, fast=fast)
    finally:
        reader.close()


def _read(p: Path, reader: Any, imu_topic: str | None, temperature_topic: str | None, *,
          ros1: bool, fast: bool = True) -> list[Run]:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    decode = store.deserialize_ros1 if ros1 else store.deserialize_cdr
    topics = {c.topic: c.msgtype for c in reader.connections}
    imus = sorted(t for t, m in topics.items() if m == IMU_TYPE)
    temps = sorted(t for t, m in topics.items() if m == TEMPERATURE_TYPE)
    if imu_topic is not None:
        if imu_topic not in imus:
            raise RunFileError(f"{p}: IMU topic {imu_topic!r} is not a {IMU_TYPE} topic of the "
                               f"bag; candidates: {imus}")
        imus = [imu_topic]
    if not imus:
        raise RunFileError(f"{p}: no {IMU_TYPE} topic in the bag (topics: "
                           f"{sorted(f'{t} [{m}]' for t, m in topics.items())})")
    pairs = {imu: _pick_temperature(p, imu, temps, temperature_topic) for imu in imus}
    fallback = ""
    if fast and not ros1 and p.is_file() and content_kind(p) == "mcap":
        from gyrotherm.readers._fast_common import Fallback
        from gyrotherm.readers._fast_rosbag import gather

        try:
            return _runs(p, pairs, *gather(p, sorted(pairs), sorted(set(pairs.values()))),
                         fallback="")
        except Fallback as exc:
            fallback = f"decoded by rosbags: {exc}"
    imu, temp, missing = _gather(p, reader, decode, pairs)
    return _runs(p, pairs, imu, temp, missing, fallback=fallback, ros1=ros1)


ImuRows = dict[tuple[str, str], tuple[NDArray[np.int64], NDArray[np.float64]]]
"""(topic, frame_id) → stamps (ns) and the (n, 6) values, in the order rosbags reads."""
TempRows = dict[str, NDArray[np.float64]]
"""temperature topic → (n, 2) rows of stamp (ns, as float) and °C, in that order."""


def _gather(p: Path, reader: Any, decode: Any, pairs: dict[str, str]
            ) -> tuple[ImuRows, TempRows, dict[str, int]]:
    """The IMU and temperature rows, each message decoded by rosbags."""
    wanted = set(pairs) | set(pairs.values())
    imu_rows: dict[tuple[str, str], _Rows] = {}
    temp_rows: dict[str, list[tuple[int, float]]] = {t: [] for t in pairs.values()}
    stamp_missing: dict[str, int] = {}
    try:
        for conn, log_ns, raw in reader.messages([c for c in reader.connections
                                                  if c.topic in wanted]):
            msg: Any = decode(raw, conn.msgtype)
            ns = _stamp_ns(msg)
            if conn.msgtype == TEMPERATURE_TYPE:
                temp_rows[conn.topic].append((ns or log_ns, float(msg.temperature)))
                continue
            if ns == 0:
                stamp_missing[conn.topic] = stamp_missing.get(conn.topic, 0) + 1
                ns = log_ns
            w, a = msg.angular_velocity, msg.linear_acceleration
            has_acc = float(msg.linear_acceleration_covariance[0]) != -1.0
            has_rate = float(msg.angular_velocity_covariance[0]) != -1.0
            nan = float("nan")
            key = (conn.topic, msg.header.frame_id)
            rows = imu_rows.get(key)
            if rows is None:
                rows = imu_rows[key] = _Rows()
            rows.append(ns, ((w.x, w.y, w.z) if has_rate else (nan, nan, nan))
                        + ((a.x, a.y, a.z) if has_acc else (nan, nan, nan)))
    except Exception as exc:  # truncated/corrupt storage, undecodable message
        raise RunFileError(f"{p}: unreadable message in the bag: {exc}") from exc
    return ({k: r.arrays() for k, r in imu_rows.items()},
            {t: np.asarray(v, dtype=np.float64).reshape(-1, 2) for t, v in temp_rows.items()},
            stamp_missing)


def _runs(p: Path, pairs: dict[str, str], imu_rows: ImuRows, temp_rows: TempRows,
          stamp_missing: dict[str, int], *, fallback: str, ros1: bool = False) -> list[Run]:
    """One run per (IMU topic, frame_id), each with its temperature topic held."""
    fmt = "rosbag1" if ros1 else "mcap" if content_kind(p) == "mcap" else "rosbag2"
    sha = sha256_of(p)
    runs: list[Run] = []
    frames_of = Counter(t for t, _ in imu_rows)
    for (topic, frame) in sorted(imu_rows):
        ttopic = pairs[topic]
        tt = temp_rows[ttopic]
        if not len(tt):
            raise RunFileError(f"{p}: temperature topic {ttopic!r} has no message "
                               f"(IMU topic {topic!r})")
        keep, _, _ = sort_unique(tt[:, 0])
        stamps, a = imu_rows.pop((topic, frame))
        time_s = (stamps // 1_000_000_000).astype(np.float64) \
            + (stamps % 1_000_000_000) * S_PER_NS
        temperature = hold_previous(tt[keep, 0], tt[keep, 1], stamps.astype(np.float64))
        device = topic if frames_of[topic] == 1 else f"{topic}[{frame}]"
        meta = {
            "format": fmt, "device_id": device, "instance": str(len(runs)),
            "imu_topic": topic, "frame_id": frame, "temperature_topic": ttopic,
            "time_field": "header.stamp" if topic not in stamp_missing
            else f"log time for {stamp_missing[topic]} message(s) with a zero header.stamp",
            "unit_time": "ns", "unit_temperature": "degC", "unit_rate": "rad/s",
            "unit_accel": "m/s2",
            "rows_before_first_temperature": str(int(np.count_nonzero(np.isnan(temperature)))),
            **({FALLBACK_KEY: fallback} if fallback else {}),
        }
        runs.append(make_run(
            path=p, device=device, where=f"IMU topic {topic!r} frame_id {frame!r}",
            time_s=time_s, temperature_c=temperature,
            rates={ax: a[:, k] for k, ax in enumerate("xyz")}, rate_to_dps=DEG_PER_RAD,
            accel_mps2={ax: a[:, 3 + k] for k, ax in enumerate("xyz")},
            metadata=meta, sha256=sha))
        del a, stamps
    return runs
