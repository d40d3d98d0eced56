"""The per-frame pipeline: decode → estimate → compensate → encode → publish.

Pure processing, no I/O of its own: frames go in through :meth:`Pipeline.process`,
payloads leave through a :class:`Sink` (Zenoh publishers in the daemon, lists in
tests). Per rate frame it only decodes, subtracts a cached bias, encodes and
publishes; the estimator and the compensator (:mod:`._compensation`) run per
*temperature* frame, where T and ΔT change. With an estimator ``update_period_s``
P > 0 (a calibration fitted on a sensor that refreshes every P s) a temperature
frame is fused only when it opens a new slot ``floor(t / P)``
(:meth:`TemperatureEstimator.update`, the rule offline features use): a sensor
that repeats its held reading in faster frames is fused once per refresh, as in the
fit; the other frames step the compensator at the unchanged estimate.

Accounting: every frame handed to :meth:`process` is either published or dropped with
a reason, so ``frames_received == frames_published + sum(drops.values())`` at all
times (:mod:`gyrotherm.daemon._accounting`: the reasons, :class:`Sink`, :class:`Counters`).

Before the first temperature frame rates are published uncorrected
(bias 0) with ``TEMPERATURE_STALE | ESTIMATOR_WARMUP`` set.

Boot-time zero (``zero``, optional; :mod:`gyrotherm.compensation._zero`): while
it is pending each rate frame's residual ω − b is pushed to it (frames flagged
stale, bias-invalid or sensor-fault discard the open window; its deadline runs on);
``ZERO_PENDING`` is set until a window is accepted, from then on the bias
removed is b + z, or ``ZERO_FAILED`` after its deadline. Once decided, the
rate path is the same as without a zero.

Time stamps: each stream (rate, temperature) has a window around a reference
stamp; frames outside it are dropped as ``bad_timestamp`` and a run of
consistent ones changes the time base (:mod:`gyrotherm.daemon._timewindow`,
docs/model.md "Time stamps the daemon believes"). The check costs one
subtraction and two comparisons per rate frame.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from gyrotherm._errors import ConfigError, PublishError
from gyrotherm.bus import TransportItem
from gyrotherm.codecs import FrameDecoder, RateSample, Rejection, RejectReason, TemperatureSample
from gyrotherm.codecs._wire import (
    HealthMessage,
    StateMessage,
    StatusFlags,
    encode_rate_values,
    encode_state,
)
from gyrotherm.compensation import Calibration
from gyrotherm.compensation._zero import BootZero, ZeroConfig, ZeroStatus
from gyrotherm.daemon._accounting import (
    INTERNAL_ERROR,
    NO_SUBSCRIBER,
    PUBLISH_ERROR,
    Counters,
    Sink,
)
from gyrotherm.daemon._compensation import (
    DEFAULT_TEMPERATURE_RANGE_C,
    POWER_ON_GAP_S,
    Compensation,
)
from gyrotherm.daemon._timewindow import (
    BAD_TIMESTAMP,
    MAX_ABS_TIME_S,
    MAX_TIME_JUMP_S,
    TIME_BASE_FRAMES,
    TimeWindow,
)
from gyrotherm.estimators import EstimatorConfig, TemperatureEstimate, TemperatureEstimator

if TYPE_CHECKING:  # loaded only when [learn] is configured (daemon._imu)
    from gyrotherm.daemon._learner import Learner

log = logging.getLogger("gyrotherm.daemon")

#: Temperature readings fused before the estimate counts as converged.
WARMUP_UPDATES = 20
#: Margin around the DBC's temperature range for restored temperatures, °C.
SENSOR_RANGE_MARGIN_C = 10.0
_ZERO = (0.0, 0.0, 0.0)
#: Rate frames that cannot count towards the boot-time zero.
_ZERO_UNUSABLE = int(StatusFlags.TEMPERATURE_STALE | StatusFlags.BIAS_INVALID
                     | StatusFlags.SENSOR_FAULT | StatusFlags.NO_CALIBRATION)
__all__ = ["BAD_TIMESTAMP", "INTERNAL_ERROR", "MAX_ABS_TIME_S", "MAX_TIME_JUMP_S",
           "NO_SUBSCRIBER", "PUBLISH_ERROR", "TIME_BASE_FRAMES", "Counters", "Pipeline", "Sink"]


#: A corrected-rate observer: (receive_time_s, x_dps, y_dps, z_dps).
RateTap = Callable[[float, float, float, float], None]


def _log_zero(zero: BootZero, time_s: float) -> None:
    """The journal line of a decided boot-time zero (once per power-on)."""
    since = time_s - zero.start_s
    if zero.status == ZeroStatus.DONE:
        log.info("boot-time zero done at t = %r s (%.1f s after the start, %d windows "
                 "refused): x %+.5f, y %+.5f, z %+.5f °/s", time_s, since,
                 zero.windows_rejected, *zero.offset_dps)
    else:
        log.warning("boot-time zero failed: no window at rest within deadline_s = %g s "
                    "(%d windows refused); only the calibration's bias is removed until "
                    "the next power-on", zero.config.deadline_s, zero.windows_rejected)


#: A sensor silence counts as a power cycle the daemon can trust when the wall clock saw
#: at least this share of it too; stamps that jumped ahead faster than the wall clock (a
#: clock step, or frames replayed faster than real time) make a power-on whose boot-time
#: zero is untrusted (``ZERO_UNVERIFIED`` unless it agrees with the previous offset).
WALL_SILENCE_SHARE = 0.5


def _wall_saw(wall_gap_s: float, sensor_gap_s: float) -> bool:
    return wall_gap_s >= WALL_SILENCE_SHARE * sensor_gap_s  # NaN: False


class Pipeline(TimeWindow):
    """Frame processing for one sensor; not thread-safe (one receiving thread)."""

    def __init__(
        self,
        decoder: FrameDecoder,
        sink: Sink,
        *,
        calibration: Calibration | None,
        estimator: EstimatorConfig | None = None,
        check_counters: bool = True,
        max_time_jump_s: float = MAX_TIME_JUMP_S,
        time_base_frames: int = TIME_BASE_FRAMES,
        power_on_gap_s: float = POWER_ON_GAP_S,
        zero: ZeroConfig | None = None,
    ) -> None:
        self._init_window(max_time_jump_s, time_base_frames)
        if not (math.isfinite(power_on_gap_s) and power_on_gap_s > 0):
            raise ConfigError(f"power_on_gap_s = {power_on_gap_s!r}: must be a positive "
                              "number of seconds")
        self._power_on_gap_s = float(power_on_gap_s)
        dbc = decoder.temperature_range_c()
        self._compensation = Compensation(
            None, self._power_on_gap_s, zero,
            temperature_range_c=DEFAULT_TEMPERATURE_RANGE_C if dbc is None else (
                dbc[0] - SENSOR_RANGE_MARGIN_C, dbc[1] + SENSOR_RANGE_MARGIN_C))
        # a power-on taken on one stream, not to be taken again when the other stream's
        # first frame after it shows the same silence or time base change
        self._power_on_waits_for: str | None = None
        self._zeroing = False  # a boot-time zero is pending: rate frames feed it
        self._decoder = decoder
        self.learn: Learner | None = None
        """The ``[learn]`` mode (:meth:`attach_learner`), fed raw rates and estimates."""
        self.rate_tap: RateTap | None = None
        """Called with (receive_time_s, x, y, z) of every corrected rate published or not
        (the consistency check of several IMUs, :mod:`gyrotherm.daemon._consistency`)."""
        self._check_counters = check_counters
        self._sink = sink
        self._default_estimator = estimator or EstimatorConfig()
        self._received = 0
        self._rate_published = 0
        self._state_published = 0
        self._drops: Counter[str] = Counter()
        self._rate_seq = 0
        self._state_seq = 0
        self._last_counter: int | None = None
        self.last_sensor_time_s: float | None = None
        self._last_temperature_s = -math.inf
        self._sensor_status = 0  # status signal of the latest temperature frame
        self.calibration: Calibration | None = None
        self._estimator = TemperatureEstimator(self._default_estimator)
        self._bias: tuple[float, float, float] = _ZERO
        self._flags = StatusFlags.TEMPERATURE_STALE | StatusFlags.ESTIMATOR_WARMUP
        self.last_estimate: TemperatureEstimate | None = None
        self.set_calibration(calibration)

    # --- configuration ---------------------------------------------------------------

    def set_calibration(self, calibration: Calibration | None) -> None:
        """Swap the calibration; a new estimator setting restarts the estimator. The
        same calibration keeps its compensator (the effects' state continues); another
        one: :mod:`gyrotherm.daemon._compensation`."""
        est = calibration.estimator if calibration else self._default_estimator
        if est != self._estimator.config:
            self._estimator = TemperatureEstimator(est)
            self.last_estimate = None
        self.calibration = calibration
        self._compensation.set_calibration(calibration)
        self._max_jump_s = max(self._max_time_jump_s, self._estimator.config.stale_after_s)
        self._refresh_bias(step=False)

    def attach_learner(self, learner: Learner) -> None:
        """Feed ``learner`` (:mod:`gyrotherm.daemon._learner`): every raw rate, every new
        estimate, every power-on; its progress goes on the state message."""
        self.learn = learner
        self._compensation.power_on_listener = learner.power_on

    @property
    def decoder(self) -> FrameDecoder:
        return self._decoder

    @property
    def frames_received(self) -> int:
        """Frames handed to :meth:`process` so far."""
        return self._received

    @property
    def compensation(self) -> Compensation:
        """The compensator and power-on time (persistence: ``snapshot``/``restore_at_power_on``)."""
        return self._compensation

    @property
    def stale_after_s(self) -> float:
        return self._estimator.config.stale_after_s

    # --- hot path ----------------------------------------------------------------------

    def process(self, msg: Any, receive_time_s: float) -> None:
        """Handle one CAN frame received at wall-clock ``receive_time_s`` (s).

        Never raises: a frame that cannot be handled is dropped with a reason
        (``bad_timestamp`` for a time stamp outside its stream's window, see the
        module docstring; ``internal_error`` for an unexpected exception, logged),
        and the stream goes on.
        """
        self._received += 1
        if type(msg) is TransportItem:  # read from the link, but not a frame
            self._drops[msg.reason] += 1
            return
        try:
            result = self._decoder.decode(msg)
            kind = type(result)
            if kind is RateSample:
                t = result.time_s
                w = self._max_jump_s
                d = t - self._rate_ref_s
                base = not (-w <= d <= w or 0.0 < d <= w + receive_time_s - self._rate_rx_s)
                if not base or self._rate_time_base(t):  # NaN: a time base (or a drop)
                    if t > self._rate_ref_s:
                        self._rate_ref_s = t
                    prev_rx, self._rate_rx_s = self._rate_rx_s, receive_time_s
                    self._rate_run_n = 0
                    self._on_rate(result, receive_time_s, base,  # type: ignore[arg-type]
                                  receive_time_s - prev_rx)
                else:
                    self._drops[BAD_TIMESTAMP] += 1
                    counter = result.counter  # type: ignore[union-attr]
                    if counter is not None:  # received, not lost: no COUNTER_JUMP next
                        self._last_counter = counter
            elif kind is TemperatureSample:
                self._on_temperature(result, receive_time_s)  # type: ignore[arg-type]
            else:
                assert isinstance(result, Rejection)
                self._drops[result.reason.value] += 1
        except Exception:
            self._drops[INTERNAL_ERROR] += 1
            n = self._drops[INTERNAL_ERROR]
            if n & (n - 1) == 0:  # log the 1st, 2nd, 4th, 8th … occurrence
                log.exception("frame %d could not be processed (%d so far); "
                              "dropped as internal_error", self._received, n)

    def _on_rate(self, s: RateSample, receive_time_s: float, base: bool,
                 wall_gap_s: float) -> None:
        t = s.time_s
        prev = self.last_sensor_time_s
        self.last_sensor_time_s = t
        if self._power_on_waits_for == "rate":  # taken on the temperature stream already
            self._power_on_waits_for = None
        elif prev is not None and base:
            self._rate_power_on(t, f"rate frames: time base changed from {prev!r} s",
                                time_base=True, receive_time_s=receive_time_s)
        elif (prev is not None and t - prev > self._power_on_gap_s
              and t - self._last_temperature_s > self._power_on_gap_s
              and self._last_temperature_s > -math.inf):
            seen = _wall_saw(wall_gap_s, t - prev)
            self._rate_power_on(t, f"both streams silent for "
                                f"{t - max(prev, self._last_temperature_s):.1f} s (> "
                                f"power_on_gap_s = {self._power_on_gap_s:g} s), a rate frame "
                                "first" + ("" if seen else "; the wall clock did not see the "
                                           "silence: the zero is untrusted"), time_base=not seen,
                                receive_time_s=receive_time_s)
        flags = self._flags
        if t - self._last_temperature_s > self._estimator.config.stale_after_s:
            flags |= StatusFlags.TEMPERATURE_STALE
        if s.counter is not None and self._check_counters:
            last = self._last_counter
            if last is not None and s.counter != (last + 1) & 0xF:
                flags |= StatusFlags.COUNTER_JUMP
            self._last_counter = s.counter
        b0, b1, b2 = self._bias
        x, y, z = s.rate_x_dps, s.rate_y_dps, s.rate_z_dps
        learn = self.learn
        if learn is not None:
            learn.on_rate(x, y, z)
        if self._zeroing:
            zero = self._compensation.zero
            assert zero is not None
            if (zero.interrupt(t) if int(flags) & _ZERO_UNUSABLE
                    else zero.push(t, x - b0, y - b1, z - b2)):  # decided: the bias changes
                _log_zero(zero, t)
                self._refresh_bias(step=False)
                flags = self._flags | (flags & (StatusFlags.TEMPERATURE_STALE
                                                | StatusFlags.COUNTER_JUMP))
                b0, b1, b2 = self._bias
        tap = self.rate_tap
        if tap is not None:
            tap(receive_time_s, x - b0, y - b1, z - b2)
        try:
            routed = self._sink.put_rate(encode_rate_values(
                self._rate_seq, t, receive_time_s, x - b0, y - b1, z - b2, x, y, z,
                b0, b1, b2, int(flags)))
        except PublishError:
            self._drops[PUBLISH_ERROR] += 1
            return
        self._rate_seq += 1
        if routed is True or routed is None:
            self._rate_published += 1
        else:  # False: nobody subscribed; a string: the sink's drop reason
            self._drops[NO_SUBSCRIBER if routed is False else routed] += 1

    def _rate_power_on(self, t: float, why: str, *, time_base: bool,
                       receive_time_s: float) -> None:
        """A power-on seen first on the rate stream (``why``): both streams were silent
        longer than ``power_on_gap_s``, or the rate stream's time base changed (a clock
        step or a reboot: the zero starts untrusted). The estimate from before is
        dropped (rates go out uncorrected, ``TEMPERATURE_STALE | ESTIMATOR_WARMUP``, as
        at start, until the first temperature frame) and the zero starts again; the
        temperature stream's matching silence or time base change is not a second one."""
        log.info("%s: power-on at t = %r s", why, t)
        self._power_on_waits_for = "temperature"
        self._estimator.reset()
        self.last_estimate = None
        self._compensation.power_on(t, first=False, time_base=time_base,
                                    receive_time_s=receive_time_s)
        self._refresh_bias(step=False)

    def _on_temperature(self, s: TemperatureSample, receive_time_s: float) -> None:
        t = s.time_s
        last = self._last_temperature_s
        if not (last < t <= last + self._max_jump_s  # NaN: True
                or last < t <= last + self._max_jump_s + receive_time_s - self._temperature_rx_s):
            n = self._time_run(t, self._temperature_run_s, self._temperature_run_n)
            first = last == -math.inf
            if not n or not (first or n >= self._time_base_frames):
                self._temperature_run_s, self._temperature_run_n = t, n
                self._drops[BAD_TIMESTAMP] += 1
                self._temperature_dropping = True
                self._flags |= StatusFlags.TEMPERATURE_STALE
                return
            if not first:  # a new time base: the estimator starts again on this reading
                self.time_base_changes["temperature"] += 1
                log.warning("temperature frames: time base changed from %r s to %r s "
                            "(%d consecutive frames); estimator restarted", last, t, n)
                self._estimator.reset()
            if self._power_on_waits_for == "temperature":
                pass  # the power-on was taken on the rate stream
            else:  # a new time base: power-on (a clock step or a reboot: untrusted zero)
                self._compensation.power_on(t, first=first, time_base=not first,
                                            receive_time_s=receive_time_s)
                self._power_on_waits_for = None if first else "rate"
        elif t - last > self._power_on_gap_s:  # a silence longer than the gap: power-on,
            rate_t = self.last_sensor_time_s  # unless the rate frames kept coming
            if self._power_on_waits_for == "temperature":
                pass  # the power-on was taken at the first rate frame after the silence
            elif rate_t is not None and t - rate_t <= self._power_on_gap_s:
                log.warning("temperature frames silent for %.1f s while rate frames kept "
                            "coming: not a power-on (effects and zero continue)", t - last)
            else:  # a silence the wall clock did not see: the stamps jumped (untrusted)
                self._compensation.power_on(t, first=False, time_base=not _wall_saw(
                    receive_time_s - self._temperature_rx_s, t - last),
                    receive_time_s=receive_time_s)
        if self._power_on_waits_for == "temperature":
            self._power_on_waits_for = None
        self._temperature_run_n = 0
        self._temperature_rx_s = receive_time_s
        self._temperature_dropping = False
        self.last_estimate = self._estimator.update(t, s.temperature_c)  # one per slot
        if self.learn is not None:  # may swap in an adopted calibration, between frames
            self.learn.on_estimate(self.last_estimate, self._compensation.power_on_s,
                                   not s.status, receive_time_s)
        self._last_temperature_s = t
        self._sensor_status = s.status or 0
        self._refresh_bias(step=True)
        self._publish_state(s.time_s, receive_time_s)

    # --- temperature-rate work ---------------------------------------------------------

    def _refresh_bias(self, *, step: bool) -> None:
        """Bias and flags from the latest estimate; ``step``: a new estimate, which steps
        the compensator (:mod:`gyrotherm.daemon._compensation`; else its cached result
        is reused). A calibration that evaluates to a non-finite bias, or overflows,
        at this (T, ΔT) gives bias 0 (the published rate is the raw rate, never a
        non-finite one) and ``BIAS_INVALID``."""
        est = self.last_estimate
        flags = StatusFlags.NONE
        modelled = not (est is None or math.isnan(est.temperature_c))
        if est is None or math.isnan(est.temperature_c):
            self._bias = _ZERO
            flags |= StatusFlags.TEMPERATURE_STALE | StatusFlags.ESTIMATOR_WARMUP
        else:
            if est.stale:
                flags |= StatusFlags.TEMPERATURE_STALE
            if est.rejected:
                flags |= StatusFlags.ESTIMATOR_REJECTED
            if est.updates < WARMUP_UPDATES:
                flags |= StatusFlags.ESTIMATOR_WARMUP
            self._bias, bias_flags = self._compensation.bias(
                est.time_s, est.temperature_c, est.delta_t_c, step=step)
            flags |= bias_flags
        zero = self._compensation.zero
        status = ZeroStatus.OFF if zero is None else zero.status
        self._zeroing = status == ZeroStatus.PENDING
        if status == ZeroStatus.PENDING:
            flags |= StatusFlags.ZERO_PENDING
        elif status == ZeroStatus.FAILED:
            flags |= StatusFlags.ZERO_FAILED
        elif (status == ZeroStatus.DONE and zero is not None and modelled
              and not flags & StatusFlags.BIAS_INVALID):
            if zero.unverified:
                flags |= StatusFlags.ZERO_UNVERIFIED
            z0, z1, z2 = zero.offset_dps
            b0, b1, b2 = self._bias
            self._bias = (b0 + z0, b1 + z1, b2 + z2)
        if self.calibration is None:
            flags |= StatusFlags.NO_CALIBRATION
        if self._sensor_status:
            flags |= StatusFlags.SENSOR_FAULT
        if self._temperature_dropping:
            flags |= StatusFlags.TEMPERATURE_STALE
        self._flags = flags

    def _publish_state(self, sensor_time_s: float, receive_time_s: float) -> None:
        est = self.last_estimate
        nan = math.nan
        msg = StateMessage(
            self._state_seq, sensor_time_s, receive_time_s,
            est.temperature_c if est else nan, est.temperature_std_c if est else nan,
            est.delta_t_c if est else nan, est.delta_t_std_c if est else nan,
            self._bias, self._flags, self._compensation.axis_effects(),
            self._compensation.zero_state(), None if self.learn is None else self.learn.progress)
        try:
            routed = self._sink.put_state(encode_state(msg))
        except PublishError:
            self._drops[PUBLISH_ERROR] += 1
            return
        self._state_seq += 1
        if routed is True or routed is None:
            self._state_published += 1
        else:  # False: nobody subscribed; a string: the sink's drop reason
            self._drops[NO_SUBSCRIBER if routed is False else routed] += 1

    def tick(self) -> None:
        """Housekeeping (≈ once a second): predict-only to the latest rate frame's stamp
        ``t`` when temperature frames stopped, i.e. while ``stale_after_s < t −
        t_temperature ≤ W`` (the window, module docstring). Beyond ``W`` the estimate
        is held, still flagged stale: a longer extrapolation of T means nothing, and
        a larger difference means the rate and temperature streams are in different
        time bases (one of them has just changed it). ``t`` passed the rate window,
        so no absurd stamp reaches the estimator."""
        t = self.last_sensor_time_s
        if (t is not None and self._estimator.initialised
                and self._estimator.config.stale_after_s < t - self._last_temperature_s
                <= self._max_jump_s):
            try:
                self.last_estimate = self._estimator.predict(t)
            except (ArithmeticError, ValueError):  # defensive: predict() does not raise
                log.warning("predict-only step to t = %r s failed; estimate kept", t)
            self._refresh_bias(step=True)

    # --- reporting ---------------------------------------------------------------------

    @property
    def flags(self) -> StatusFlags:
        return self._flags

    def counters(self) -> Counters:
        return Counters(
            frames_received=self._received,
            frames_published=self._rate_published + self._state_published,
            rate_published=self._rate_published,
            state_published=self._state_published,
            drops=dict(self._drops),
            counter_jumps=self._decoder.stats().events[RejectReason.COUNTER_JUMP],
        )

    def health(self, *, seq: int, receive_time_s: float, uptime_s: float,
               calibration_id: str, extra_flags: StatusFlags = StatusFlags.NONE
               ) -> HealthMessage:
        """A health message; ``extra_flags`` adds what only the caller knows (a silent bus)."""
        c = self.counters()
        return HealthMessage(seq, self.last_sensor_time_s, receive_time_s, uptime_s,
                             c.frames_received, c.frames_published, c.drops,
                             self._flags | extra_flags, calibration_id, c.counter_jumps)
