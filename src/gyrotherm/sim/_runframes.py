"""Frame streams: a run (or a ``candump -l`` log) as CAN frames in time order.

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
stream is created (:mod:`gyrotherm.sim._framepack`, checked against the
``FrameEncoder``, whose rolling counters continue after the run). Only the
``can.Message`` objects are created lazily (≈1 µs a frame).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import NamedTuple

import can
import numpy as np

from gyrotherm._errors import ConfigError, DecodeError
from gyrotherm.codecs._candump import read_candump
from gyrotherm.codecs._canenc import FrameEncoder
from gyrotherm.codecs._canmap import DEFAULT_DBC_PATH, Layout, SignalMap, resolve_layout
from gyrotherm.codecs._runfile import TEMPERATURE_PERIOD_KEY as TEMPERATURE_PERIOD_KEY
from gyrotherm.codecs._runfile import Run
from gyrotherm.sim._framepack import _encode_rows

DEFAULT_TEMPERATURE_PERIOD_S = 0.1
"""Temperature frame period when neither the caller nor the run names one, s."""
"""Run metadata key read for the temperature frame period, s."""

RATE, TEMPERATURE, OTHER = 0, 1, 2
"""Frame kinds, as the values of :attr:`FrameStream.kinds`."""


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
    if temperature_period_s is None:
        recorded = run.temperature_period_s()  # RunFileError when malformed
        return DEFAULT_TEMPERATURE_PERIOD_S if recorded is None else recorded
    value = temperature_period_s
    if not (math.isfinite(value) and value >= 0):
        raise ConfigError(
            f"temperature_period_s: must be a finite number of seconds >= 0, got {value!r}"
        )
    return float(value)


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
                yield from self._flagged(
                    message(timestamp=t, arbitration_id=t_id, is_extended_id=t_ext,
                            data=temp_data[j], is_fd=t_fd), saturated=temp_sat[j])
                j += 1
            yield from self._flagged(
                message(timestamp=t, arbitration_id=r_id, is_extended_id=r_ext,
                        data=rate_data[i], is_fd=r_fd), saturated=rate_sat[i])

    def _flagged(self, msg: can.Message, *, saturated: bool) -> Iterator[can.Message]:
        """Yield ``msg``; a saturated one is counted and flagged while it is out."""
        if saturated:
            self.saturated += 1
            self.last_saturated = True
        yield msg
        self.last_saturated = False


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
