"""The time-stamp window of the pipeline's two streams (a mixin of
:class:`~gyrotherm.daemon._pipeline.Pipeline`, which inlines the in-window checks
on its hot path and calls here only for out-of-window stamps).

Time stamps (docs/model.md, "Time stamps the daemon believes"). Each stream
(rate, temperature) has a window around a reference stamp ``t_ref``,
``W = max(max_time_jump_s, stale_after_s)`` (default 60 s):

* a rate frame is accepted when ``|t − t_ref| ≤ W``, ``t_ref`` the largest
  accepted rate stamp (steps back and repeated stamps inside the window are
  published as before, and cannot walk ``t_ref`` back);
* a temperature frame is accepted when ``t_ref < t ≤ t_ref + W``, ``t_ref`` the
  latest accepted temperature stamp: strictly newer and at most ``W`` ahead, so the
  estimator's time only moves forward, by at most ``W`` per reading;
* a stamp further ahead is still accepted when the jump is no larger than ``W``
  plus the wall-clock time that passed since the stream's last accepted frame
  arrived (``receive_time_s``): a gyro that falls silent and comes back, or a
  bus reopened after minutes, resumes without losing a frame;
* any other frame (NaN, ±inf, |t| > ``MAX_ABS_TIME_S`` = 10¹² s, a jump beyond
  that, a step back or repeat in the temperature stream) is dropped as
  ``bad_timestamp`` and changes neither the window nor the estimator (a dropped
  rate frame's CAN counter is still noted); while the latest temperature frame
  was so dropped, every message carries ``TEMPERATURE_STALE``;
* a time base change (sensor reboot, clock step) is recognised when
  ``time_base_frames`` (default 5) consecutive out-of-window frames of one
  stream are strictly increasing with steps ≤ ``W``: the last of them is
  accepted as the new ``t_ref`` (the temperature stream also restarts the
  estimator: ``ESTIMATOR_WARMUP`` for the next 20 readings), i.e. at most 4
  frames per stream are lost. The first frame of a stream needs only
  ``|t| ≤ MAX_ABS_TIME_S``.

So a burst of fewer than ``time_base_frames`` bad stamps per stream changes
nothing but the drop count (and the stale flag until the next good temperature
frame): the next good frames give exactly the messages of a stream that never
contained the burst (rate ``seq`` aside, when rate stamps of the burst lay inside
the window and were published). The check costs one subtraction and two
comparisons per rate frame.
"""

from __future__ import annotations

import logging
import math

from gyrotherm._errors import ConfigError

log = logging.getLogger("gyrotherm.daemon")

#: Drop reason: the frame's time stamp is outside its stream's window (module docstring).
BAD_TIMESTAMP = "bad_timestamp"
#: Default half-width of a stream's time stamp window, s (at least ``stale_after_s``).
MAX_TIME_JUMP_S = 60.0
#: Default number of consecutive consistent out-of-window frames that change the time base.
TIME_BASE_FRAMES = 5
#: Largest |time stamp| ever accepted, s (10¹² s ≈ 31 700 years: Unix-epoch and
#: power-on clocks are far inside; float spacing there is still 0.12 ms).
MAX_ABS_TIME_S = 1e12


class TimeWindow:
    """Per stream: the reference stamp and the run of out-of-window stamps."""

    _max_jump_s: float

    def _init_window(self, max_time_jump_s: float, time_base_frames: int) -> None:
        if not (math.isfinite(max_time_jump_s) and max_time_jump_s > 0):
            raise ConfigError(f"max_time_jump_s = {max_time_jump_s!r}: must be a positive "
                              "number of seconds")
        if isinstance(time_base_frames, bool) or not (
                isinstance(time_base_frames, int) and time_base_frames >= 2):
            raise ConfigError(f"time_base_frames = {time_base_frames!r}: must be an integer >= 2")
        self._max_time_jump_s = float(max_time_jump_s)
        self._max_jump_s = self._max_time_jump_s  # W, widened to stale_after_s by the owner
        self._time_base_frames = time_base_frames
        self._rate_ref_s = math.nan
        self._rate_rx_s = math.nan  # receive time of the last accepted rate frame, s
        self._temperature_rx_s = math.nan  # … of the last accepted temperature frame, s
        self._rate_run_s = math.nan
        self._rate_run_n = 0
        self._temperature_run_s = math.nan
        self._temperature_run_n = 0
        self._temperature_dropping = False  # the latest temperature frame: bad_timestamp
        self.time_base_changes: dict[str, int] = {"rate": 0, "temperature": 0}
        """Time base changes accepted per stream (module docstring)."""

    def _time_run(self, t: float, run_s: float, run_n: int) -> int:
        """Length of the run of out-of-window stamps that ``t`` makes: ``run_n + 1`` when
        it continues the run (``run_s < t ≤ run_s + W``), 1 when it starts one, 0
        when it can never be a time stamp (non-finite or beyond MAX_ABS_TIME_S)."""
        if not -MAX_ABS_TIME_S <= t <= MAX_ABS_TIME_S:
            return 0
        if run_n and run_s < t <= run_s + self._max_jump_s:
            return run_n + 1
        return 1

    def _rate_time_base(self, t: float) -> bool:
        """A rate stamp outside ``|t − t_ref| ≤ W``: True when it is accepted (the
        stream's first stamp, or the frame completing a time base change)."""
        n = self._time_run(t, self._rate_run_s, self._rate_run_n)
        first = math.isnan(self._rate_ref_s)
        if n and (first or n >= self._time_base_frames):
            if not first:
                self.time_base_changes["rate"] += 1
                log.warning("rate frames: time base changed from %r s to %r s "
                            "(%d consecutive frames)", self._rate_ref_s, t, n)
            self._rate_ref_s = t
            return True
        self._rate_run_s, self._rate_run_n = t, n
        return False
