"""Play a simulated (or recorded) gyro onto a CAN bus: frame streams and a paced player.

The frame streams (:func:`frames_from_run`, :func:`frames_from_candump`,
:class:`FrameStream`: which frames a run yields, when, and how saturation and
NaN are handled) are in :mod:`gyrotherm.sim._runframes`, their vectorised
payload packing in :mod:`gyrotherm.sim._framepack`; every name of both stays
importable from here. This module plays them and holds the sinks.

:func:`play` paces frames by an absolute schedule: frame ``j`` is sent at
``t_start + (timestamp_j − timestamp_0) / speed`` of ``clock`` (no drift
accumulates); it waits with ``stop.wait(timeout)`` so a stop interrupts it, and
sends every frame already due without waiting (batches when behind).
``speed`` 0 or ``inf`` sends as fast as the sink takes them.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Protocol

import can

from gyrotherm._errors import ConfigError
from gyrotherm.bus import FrameSink
from gyrotherm.codecs._candump import format_candump_line
from gyrotherm.codecs._canmap import EXTENDED_KEY
from gyrotherm.sim._framepack import _encode_rows as _encode_rows
from gyrotherm.sim._framepack import _pack as _pack
from gyrotherm.sim._framepack import _raw_values as _raw_values
from gyrotherm.sim._framepack import _vectorisable as _vectorisable
from gyrotherm.sim._runframes import DEFAULT_TEMPERATURE_PERIOD_S as DEFAULT_TEMPERATURE_PERIOD_S
from gyrotherm.sim._runframes import OTHER as OTHER
from gyrotherm.sim._runframes import RATE as RATE
from gyrotherm.sim._runframes import TEMPERATURE as TEMPERATURE
from gyrotherm.sim._runframes import TEMPERATURE_PERIOD_KEY as TEMPERATURE_PERIOD_KEY
from gyrotherm.sim._runframes import FrameStream as FrameStream
from gyrotherm.sim._runframes import _default_kinds as _default_kinds
from gyrotherm.sim._runframes import _period as _period
from gyrotherm.sim._runframes import _Rate as _Rate
from gyrotherm.sim._runframes import _row_error as _row_error
from gyrotherm.sim._runframes import _RunFrames as _RunFrames
from gyrotherm.sim._runframes import _Temperature as _Temperature
from gyrotherm.sim._runframes import _without_channel as _without_channel
from gyrotherm.sim._runframes import frame_kinds as frame_kinds
from gyrotherm.sim._runframes import frames_from_candump as frames_from_candump
from gyrotherm.sim._runframes import frames_from_run as frames_from_run

_CHECK_EVERY = 1024  # frames between clock reads (progress) when sending without waiting


class StopSignal(Protocol):
    """What :func:`play` needs of its stop event (:class:`threading.Event` fits)."""

    def is_set(self) -> bool: ...
    def wait(self, timeout: float | None = None) -> bool: ...


@dataclass(frozen=True)
class PlayStats:
    """What :func:`play` sent. Times in seconds; ``duration_s`` is ``clock`` time."""

    frames_sent: int
    rate_frames: int
    temperature_frames: int
    duration_s: float
    saturated: int
    sensor_span_s: float = 0.0
    """Timestamp of the last frame sent minus that of the first, s."""
    stopped: bool = False
    """True when the stop event ended playback before the frames ran out."""

    @property
    def other_frames(self) -> int:
        return self.frames_sent - self.rate_frames - self.temperature_frames

    @property
    def frames_per_s(self) -> float:
        return self.frames_sent / self.duration_s if self.duration_s > 0 else math.inf


def _inverse_speed(speed: float) -> float:
    if isinstance(speed, bool) or not isinstance(speed, int | float) or not speed >= 0:
        raise ConfigError(f"speed: must be >= 0 (0 or inf: as fast as possible), got {speed!r}")
    return 0.0 if speed == 0 or math.isinf(speed) else 1.0 / speed


def play(
    frames: Iterable[can.Message],
    sink: FrameSink,
    *,
    speed: float = 1.0,
    clock: Callable[[], float] = time.monotonic,
    stop: StopSignal | None = None,
    progress: Callable[[int], None] | None = None,
    progress_interval_s: float = 1.0,
    max_frames: int | None = None,
) -> PlayStats:
    """Send ``frames`` to ``sink`` at ``speed`` × real time (module docstring).

    Stops when the frames run out, after ``max_frames`` frames, or when ``stop``
    is set (checked before every send and while waiting). ``progress`` gets the
    count sent so far, at most every ``progress_interval_s`` of ``clock`` time
    (checked before each wait and every 1024 frames). Frames are counted as
    rate / temperature by :attr:`FrameStream.kinds`, or by the shipped DBC's
    ids for a plain iterable. Exceptions of ``sink.send`` propagate.
    """
    inv_speed = _inverse_speed(speed)
    if max_frames is not None and (isinstance(max_frames, bool) or max_frames < 0):
        raise ConfigError(f"max_frames: must be an integer >= 0, got {max_frames!r}")
    stream = frames if isinstance(frames, FrameStream) else None
    kinds = stream.kinds if stream is not None else _default_kinds()
    it = stream._it if stream is not None else iter(frames)
    stop = stop if stop is not None else threading.Event()
    send, is_set, wait = sink.send, stop.is_set, stop.wait
    counts = [0, 0, 0]
    sent, limit = 0, -1 if max_frames is None else max_frames
    first_ts = last_ts = 0.0
    t_start = now = next_report = clock()
    pending = stopped = False  # pending: a frame was pulled from ``it`` but not sent
    for msg in it if limit else ():
        ts = msg.timestamp
        if sent == 0:
            first_ts, t_start = ts, clock()
            now, next_report = t_start, t_start + progress_interval_s
        elif inv_speed:
            due = t_start + (ts - first_ts) * inv_speed
            if due > now:
                now = clock()
                if progress is not None and now >= next_report:
                    progress(sent)
                    next_report = now + progress_interval_s
                while due > now and not stopped:
                    stopped = wait(due - now)
                    now = clock()
        if stopped or is_set():
            pending = stopped = True
            break
        send(msg)
        sent += 1
        last_ts = ts
        key = msg.arbitration_id + EXTENDED_KEY if msg.is_extended_id else msg.arbitration_id
        counts[kinds.get(key, OTHER)] += 1
        if sent == limit:
            break
        if progress is not None and not sent % _CHECK_EVERY:
            now = clock()
            if now >= next_report:
                progress(sent)
                next_report = now + progress_interval_s
    saturated = 0
    if stream is not None:
        saturated = stream.saturated - (1 if pending and stream.last_saturated else 0)
    return PlayStats(
        frames_sent=sent,
        rate_frames=counts[RATE],
        temperature_frames=counts[TEMPERATURE],
        duration_s=clock() - t_start if sent else 0.0,
        saturated=saturated,
        sensor_span_s=last_ts - first_ts if sent else 0.0,
        stopped=stopped,
    )


class CandumpSink(FrameSink):
    """Writes every frame sent to a ``candump -l`` log (``channel`` names the interface)."""

    def __init__(self, path: str | os.PathLike[str], *, channel: str = "vcan0") -> None:
        self.path, self.channel = Path(path), channel
        try:
            self._file: IO[str] | None = self.path.open("w", encoding="utf-8", newline="\n")
        except OSError as exc:
            raise ConfigError(f"{self.path}: cannot write candump log: {exc}") from exc
        self.frames = 0

    @property
    def is_shutdown(self) -> bool:
        return self._file is None

    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        if self._file is None:
            raise ConfigError(f"{self.path}: candump log already closed")
        self._file.write(format_candump_line(msg, channel=self.channel) + "\n")
        self.frames += 1

    def shutdown(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


class TeeSink(FrameSink):
    """Sends every frame to each of ``sinks`` in order; shuts them all down."""

    def __init__(self, *sinks: FrameSink) -> None:
        self.sinks = sinks
        self._closed = False

    @property
    def is_shutdown(self) -> bool:
        return self._closed

    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        for sink in self.sinks:
            sink.send(msg, timeout_s)

    def shutdown(self) -> None:
        self._closed = True
        for sink in self.sinks:
            sink.shutdown()


class _Flushable(Protocol):
    def send(self, msg: can.Message, timeout_s: float | None = None) -> None: ...
    def flush(self, timeout_s: float | None) -> bool: ...
    def shutdown(self) -> None: ...
    @property
    def is_shutdown(self) -> bool: ...


class FlushingSink(FrameSink):
    """Back-pressure for a sink that never blocks (``SocketcandServer``).

    Every ``every_frames`` frames it calls ``sink.flush(timeout_s)``, so a
    client's queue never holds more than ``every_frames`` frames and nothing is
    dropped while clients keep up; a client that does not read within
    ``timeout_s`` is left behind (its frames dropped) and counted in
    ``flush_timeouts``.
    """

    def __init__(self, sink: _Flushable, *, every_frames: int = 4096, timeout_s: float = 10.0):
        if isinstance(every_frames, bool) or not isinstance(every_frames, int) or every_frames < 1:
            raise ConfigError(f"every_frames: must be an integer >= 1, got {every_frames!r}")
        self.sink, self.every_frames, self.timeout_s = sink, every_frames, timeout_s
        self.flush_timeouts = 0
        self._left = every_frames

    @property
    def is_shutdown(self) -> bool:
        return self.sink.is_shutdown

    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        self.sink.send(msg, timeout_s)
        self._left -= 1
        if not self._left:
            self._left = self.every_frames
            if not self.sink.flush(self.timeout_s):
                self.flush_timeouts += 1

    def flush(self, timeout_s: float | None) -> bool:
        return self.sink.flush(timeout_s)

    def shutdown(self) -> None:
        self.sink.shutdown()
