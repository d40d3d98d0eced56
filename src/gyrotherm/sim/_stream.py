"""Play a simulated (or recorded) gyro onto a CAN bus: frame streams and a paced player.

Frames from a run (:func:`frames_from_run`), per row ``i`` of the run, in time order:

* one rate frame at ``t0_s + time_s[i]`` (axes the run lacks are sent as 0 °/s);
* one temperature frame before it, at the same time, when row ``i`` is the
  first row of a new temperature slot: slot ``k = floor(time_s / P + 1e-9)``
  with ``P`` the temperature period (row 0 always sends). So a temperature
  frame goes out at most once per ``P`` seconds and at least once per row when
  rows are further apart than ``P``; ``P = 0`` sends one with every row. The
  slots are aligned to ``time_s = 0`` exactly as the simulator refreshes its
  temperature sensor (``GyroParams.temperature_period_s``), so for simulated
  runs every new reading is sent once, at the time it appears. ``P`` is the
  ``temperature_period_s`` argument, else the run's metadata key
  ``temperature_period_s``, else :data:`DEFAULT_TEMPERATURE_PERIOD_S` (0.1 s,
  the simulator's default: at most 10 Hz).

A value outside the DBC range is clamped (``saturate=True``) and the frame is
counted in :attr:`FrameStream.saturated`; NaN raises :class:`gyrotherm.DecodeError`
naming the run, row and signal. Frame timestamps are sensor time
(``t0_s + time_s``), never the wall clock, at any playback speed.

Encoding is vectorised: payloads of all rows are packed with numpy when the
stream is created, from the DBC's own signal definitions exactly as
:class:`~gyrotherm.codecs.FrameEncoder` packs them (raw = round half to even of
``(value − offset)/scale``, clamped; two's complement; little-endian word
``raw << start`` and big-endian word as in ``_canmap``; unmapped signals 0;
rolling counter; CRC over every other byte). The first and last frame of each
message are also encoded by the ``FrameEncoder`` itself: they must match (else
``RuntimeError``), and the encoder's rolling counters continue after the run.
Messages with float signals or more than 8 bytes use the encoder row by row.
Only the ``can.Message`` objects are created lazily (≈1 µs a frame).

:func:`play` paces frames by an absolute schedule: frame ``j`` is sent at
``t_start + (timestamp_j − timestamp_0) / speed`` of ``clock`` (no drift
accumulates); it waits with ``stop.wait(timeout)`` so a stop interrupts it, and
sends every frame already due without waiting (batches when behind).
``speed`` 0 or ``inf`` sends as fast as the sink takes them.
"""

from __future__ import annotations

import functools
import math
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, NamedTuple, Protocol

import can
import numpy as np

from gyrotherm._errors import ConfigError, DecodeError
from gyrotherm.codecs._candump import format_candump_line, read_candump
from gyrotherm.codecs._canenc import FrameEncoder
from gyrotherm.codecs._canmap import (
    DEFAULT_DBC_PATH,
    EXTENDED_KEY,
    Field,
    Layout,
    MessagePlan,
    SignalMap,
    resolve_layout,
)
from gyrotherm.codecs._runfile import Run
from gyrotherm.sim._bus import FrameSink

DEFAULT_TEMPERATURE_PERIOD_S = 0.1
"""Temperature frame period when neither the caller nor the run names one, s."""
TEMPERATURE_PERIOD_KEY = "temperature_period_s"
"""Run metadata key read for the temperature frame period, s."""

RATE, TEMPERATURE, OTHER = 0, 1, 2
"""Frame kinds, as the values of :attr:`FrameStream.kinds`."""

_CHECK_EVERY = 1024  # frames between clock reads (progress) when sending without waiting


class StopSignal(Protocol):
    """What :func:`play` needs of its stop event (:class:`threading.Event` fits)."""

    def is_set(self) -> bool: ...
    def wait(self, timeout: float | None = None) -> bool: ...


def frame_kinds(layout: Layout) -> dict[int, int]:
    """Frame key (id, plus ``EXTENDED_KEY`` if extended) → :data:`RATE` / :data:`TEMPERATURE`."""
    return {layout.rate.key: RATE, layout.temperature.key: TEMPERATURE}


@functools.cache
def _default_kinds() -> Mapping[int, int]:
    return frame_kinds(resolve_layout(DEFAULT_DBC_PATH, SignalMap.default()))


class FrameStream(Iterator[can.Message]):
    """Frames in time order plus what :func:`play` counts.

    ``kinds`` classifies frames (see :func:`frame_kinds`). ``saturated`` is the
    number of frames yielded so far with a clamped value; ``last_saturated``
    tells whether the most recently yielded frame was one of them.
    """

    def __init__(self, frames: Iterable[can.Message], *, kinds: Mapping[int, int]) -> None:
        self.kinds = kinds
        self.saturated = 0
        self.last_saturated = False
        self._it: Iterator[can.Message] = iter(frames)

    def __next__(self) -> can.Message:
        return next(self._it)


class _Rate(NamedTuple):
    time_s: float
    rate_x_dps: float
    rate_y_dps: float
    rate_z_dps: float


class _Temperature(NamedTuple):
    time_s: float
    temperature_c: float


def _period(run: Run, temperature_period_s: float | None) -> float:
    if temperature_period_s is not None:
        value, where = temperature_period_s, "temperature_period_s"
    elif TEMPERATURE_PERIOD_KEY in run.metadata:
        text = run.metadata[TEMPERATURE_PERIOD_KEY]
        where = f"{run.source}: run {run.name!r} metadata {TEMPERATURE_PERIOD_KEY!r}"
        try:
            value = float(text)
        except ValueError:
            raise ConfigError(f"{where}: {text!r} is not a number of seconds") from None
    else:
        return DEFAULT_TEMPERATURE_PERIOD_S
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(f"{where}: must be a finite number of seconds >= 0, got {value!r}")
    return float(value)


def _raw_values(values: np.ndarray, f: Field) -> tuple[np.ndarray, np.ndarray]:
    """(raw values as ``FrameEncoder`` rounds them, rows it would clamp); NaN rows are kept."""
    with np.errstate(invalid="ignore", over="ignore"):
        raw = (values - f.offset) / f.scale
        if not f.is_float:
            raw = np.where(np.isfinite(raw), np.round(raw), raw)
        outside = ~((raw >= f.raw_min) & (raw <= f.raw_max)) & ~np.isnan(raw)
    return raw, outside


def _vectorisable(plan: MessagePlan, given: int) -> bool:
    """Integer signals of at most 62 bits in a classic frame, unsent values (status) may be 0."""
    fields = [*plan.values, *([plan.counter] if plan.counter is not None else [])]
    return (
        plan.compiled
        and plan.length <= 8
        and all(f.mask.bit_length() <= 62 for f in fields)
        and all(f.raw_min <= 0 <= f.raw_max for f in plan.values[given:])
    )


def _pack(plan: MessagePlan, raws: list[np.ndarray], counter_start: int) -> list[bytes]:
    """Payloads as ``FrameEncoder(saturate=True)`` builds them, one per row (see ``_canmap``).

    ``raws`` holds the first ``len(raws)`` value fields (rounded, unclamped);
    further value fields (status) are sent as raw 0, the counter runs from
    ``counter_start``, the CRC covers every other byte.
    """
    n, length = len(raws[0]), plan.length
    words = {False: np.zeros(n, np.uint64), True: np.zeros(n, np.uint64)}  # by big_endian
    columns: list[tuple[Field, np.ndarray]] = list(zip(plan.values, raws, strict=False))
    if plan.counter is not None:
        counters = (counter_start + np.arange(n, dtype=np.int64)) % plan.counter.span
        columns.append((plan.counter, counters))
    for f, raw in columns:
        clamped = np.clip(raw, f.raw_min, f.raw_max).astype(np.int64)
        words[f.big_endian] |= (clamped & f.mask).astype(np.uint64) << np.uint64(f.shift)
    little = words[False].astype("<u8").view(np.uint8).reshape(n, 8)[:, :length]
    big = words[True].astype(">u8").view(np.uint8).reshape(n, 8)[:, 8 - length :]
    data = little | big
    if plan.crc is not None and plan.crc_field is not None:
        table = np.array(plan.crc.table, dtype=np.uint8)
        r = np.full(n, plan.crc.init, dtype=np.uint8)
        crc_at = plan.crc_field.byte_index
        for j in range(length):
            if j != crc_at:
                r = table[r ^ data[:, j]]
        data[:, crc_at] = r ^ np.uint8(plan.crc.xorout)
    blob = data.tobytes()
    return [blob[i * length : (i + 1) * length] for i in range(n)]


def _encode_rows(
    plan: MessagePlan,
    columns: list[np.ndarray],
    one: Callable[[int, int | None], can.Message],
) -> tuple[list[bytes], list[bool]]:
    """(payload, saturated?) per row; ``one(row, counter)`` encodes a row with the encoder.

    The first and the last row also go through ``one`` (so the encoder's rolling
    counter continues past this run) and must equal the vectorised payloads.
    """
    n = len(columns[0])
    raws, saturated = [], np.zeros(n, dtype=bool)
    for f, values in zip(plan.values, columns, strict=False):
        raw, outside = _raw_values(values, f)
        raws.append(raw)
        saturated |= outside
    flags: list[bool] = saturated.tolist()
    nan_rows = np.flatnonzero(np.any([np.isnan(r) for r in raws], axis=0))
    if len(nan_rows):
        one(int(nan_rows[0]), None)  # raises the encoder's DecodeError for NaN
    if not n or not _vectorisable(plan, len(columns)):
        return [bytes(one(i, None).data) for i in range(n)], flags
    first = bytes(one(0, None).data)
    start, ctr = 0, plan.counter
    if ctr is not None:
        word = int.from_bytes(first, "big" if ctr.big_endian else "little")
        start = (word >> ctr.shift) & ctr.mask
    payloads = _pack(plan, raws, start)
    last = payloads[-1]
    if n > 1:
        last = bytes(one(n - 1, None if ctr is None else (start + n - 1) % ctr.span).data)
    if (first, last) != (payloads[0], payloads[-1]):
        raise RuntimeError(f"message {plan.name!r}: vectorised payloads differ from FrameEncoder")
    return payloads, flags


class _RunFrames(FrameStream):
    def __init__(self, run: Run, encoder: FrameEncoder, period_s: float, t0_s: float) -> None:
        super().__init__((), kinds=frame_kinds(encoder.layout))
        n = len(run)
        if period_s > 0 and n:
            slot = np.floor(run.time_s / period_s + 1e-9)
            temp_rows = np.flatnonzero(np.r_[True, slot[1:] != slot[:-1]])
        else:
            temp_rows = np.arange(n)
        times = t0_s + run.time_s
        zero = np.zeros(n)
        axes = [run.rates_dps.get(a, zero) for a in ("x", "y", "z")]
        temps, temp_times = run.temperature_c[temp_rows], times[temp_rows]

        def rate(i: int, counter: int | None) -> can.Message:
            sample = _Rate(float(times[i]), float(axes[0][i]), float(axes[1][i]), float(axes[2][i]))
            try:
                return encoder.encode_rate(sample, saturate=True, counter=counter)
            except DecodeError as exc:
                raise _row_error(run, i, exc) from exc

        def temperature(j: int, counter: int | None) -> can.Message:
            sample = _Temperature(float(temp_times[j]), float(temps[j]))
            try:
                return encoder.encode_temperature(sample, saturate=True, counter=counter)
            except DecodeError as exc:
                raise _row_error(run, int(temp_rows[j]), exc) from exc

        layout = encoder.layout
        rate_data, rate_sat = _encode_rows(layout.rate, axes, rate)
        temp_data, temp_sat = _encode_rows(layout.temperature, [temps], temperature)
        self._it = self._generate(
            times.tolist(), (rate_data, rate_sat), temp_rows.tolist(), (temp_data, temp_sat), layout
        )

    def _generate(
        self,
        times: list[float],
        rates: tuple[list[bytes], list[bool]],
        temp_rows: list[int],
        temperatures: tuple[list[bytes], list[bool]],
        layout: Layout,
    ) -> Iterator[can.Message]:
        message = can.Message
        (rate_data, rate_sat), (temp_data, temp_sat) = rates, temperatures
        r_id, r_ext, r_fd = layout.rate.frame_id, layout.rate.is_extended_id, layout.rate.length > 8
        temp = layout.temperature
        t_id, t_ext, t_fd = temp.frame_id, temp.is_extended_id, temp.length > 8
        temp_rows = [*temp_rows, -1]
        j = 0
        for i, t in enumerate(times):
            if i == temp_rows[j]:
                msg = message(timestamp=t, arbitration_id=t_id, is_extended_id=t_ext,
                              data=temp_data[j], is_fd=t_fd)
                j += 1
                if temp_sat[j - 1]:
                    self.saturated += 1
                    self.last_saturated = True
                    yield msg
                    self.last_saturated = False
                else:
                    yield msg
            msg = message(timestamp=t, arbitration_id=r_id, is_extended_id=r_ext,
                          data=rate_data[i], is_fd=r_fd)
            if rate_sat[i]:
                self.saturated += 1
                self.last_saturated = True
                yield msg
                self.last_saturated = False
            else:
                yield msg


def _row_error(run: Run, i: int, exc: DecodeError) -> DecodeError:
    return DecodeError(f"{run.source}: run {run.name!r} row {i} (time_s {run.time_s[i]:g}): {exc}")


def frames_from_run(
    run: Run,
    *,
    encoder: FrameEncoder,
    temperature_period_s: float | None = None,
    t0_s: float = 0.0,
) -> FrameStream:
    """Rate and temperature frames of ``run`` in time order (see the module docstring).

    Timestamps are ``t0_s + time_s`` (s). ``encoder`` supplies the DBC layout and
    the rolling counters: they continue from the encoder's state, and the
    encoder continues after the run (payloads are computed on this call; a NaN
    raises here). ``temperature_period_s`` ≥ 0 overrides the run's period.
    """
    if not math.isfinite(t0_s):
        raise ConfigError(f"t0_s: must be a finite number of seconds, got {t0_s!r}")
    return _RunFrames(run, encoder, _period(run, temperature_period_s), float(t0_s))


def _without_channel(frames: Iterable[can.Message]) -> Iterator[can.Message]:
    for msg in frames:
        msg.channel = None  # python-can's socketcan would route by it
        yield msg


def frames_from_candump(
    path: str | os.PathLike[str],
    *,
    dbc_path: str | os.PathLike[str] = DEFAULT_DBC_PATH,
    signal_map: SignalMap | None = None,
) -> FrameStream:
    """Replay a ``candump -l`` log, lazily, with the log's timestamps.

    The log's interface name is dropped (the sink decides the channel). The
    DBC and signal map only classify frames as rate / temperature for
    :class:`PlayStats`; every frame is replayed, mapped or not.
    """
    layout = resolve_layout(dbc_path, signal_map or SignalMap.default())
    try:
        Path(path).open("rb").close()  # fail now, not at the first frame played
    except OSError as exc:
        raise DecodeError(f"{path}: cannot open candump log: {exc}") from exc
    return FrameStream(_without_channel(read_candump(path)), kinds=frame_kinds(layout))


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
