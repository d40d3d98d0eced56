"""The pipeline's bias: one :class:`~gyrotherm.compensation.Compensator` per loaded
calibration, stepped once per new estimate, and the gyro's power-on time.

Version-1 and version-2 calibrations run through the same compensator (without
effects a step equals :meth:`Calibration.bias_at` bit for bit). It is stepped
with (t, T, ΔT, t_on) on each accepted temperature frame and on the
housekeeping's predict-only step, never per rate frame: the result is cached
and the rate hot path only reads the cached bias tuple.

**Power-on** (t_on = t − ``power_on_s``): the first accepted temperature frame
after the daemon starts, after a sensor silence longer than ``power_on_gap_s``
(sensor time between two accepted temperature frames, the rate frames silent
too: a temperature dropout while rates keep coming is not a power-on) or after a
time-base change of the temperature stream is the gyro's power-on: t_on = 0 there and the
effects' state starts again (as offline evaluation starts it at a run's first
row). Exception: a daemon restarted while the gyro kept running restores the
state it saved (:meth:`Compensation.restore_at_power_on`, persistence in
:mod:`gyrotherm.daemon._effects_store`) when the first frame continues the saved
time within ``power_on_gap_s``.

**Another calibration** (SIGHUP): the same calibration (equal content, e.g. the
same file re-read) keeps its compensator, nothing is stepped again. A different
one gets a new compensator; it takes over the old one's per-axis states when
both have the same axes and the same effect kinds per axis (the states then
mean the same things: structure temperature, hysteresis, power-on time), else
its states start at the current estimate (T_s = T, h = 0). t_on is the daemon's
and always continues. The new compensator is stepped once at the current
estimate (with a taken-over state that step has dt = 0, which changes nothing).

**Boot-time zero** (optional, :mod:`gyrotherm.compensation._zero`): started
(trusted) at each power-on, measured by the pipeline on the rate frames. A
restored state (the gyro kept running) keeps a zero that was done, a failed one
stays failed, a pending one goes on (:meth:`BootZero.restore`, bounds re-checked).
The same calibration keeps it. **Another calibration never re-measures a zero
that was done** (the vehicle may be moving at a reload): the offset is carried
over, z' = z + b_old − b_new, both biases at the same (current) estimate — exact
when the old model's error did not change between the zero's window and the
reload. A carried offset beyond ``max_offset_dps`` (the models disagree too much)
starts an untrusted zero instead. A failed zero stays failed, a pending one goes
on; only a calibration loaded where there was none starts an untrusted zero. No
calibration stops it (nothing is removed without one). A time-base change (a
clock step or a sensor reboot: the daemon cannot tell) starts an untrusted zero
with the previous offset as its reference.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm.codecs._wire import AxisEffects, StatusFlags, ZeroState
from gyrotherm.compensation import Calibration, Compensator
from gyrotherm.compensation._effects_state import EffectFlags
from gyrotherm.compensation._zero import BootZero, ZeroConfig, ZeroStatus
from gyrotherm.daemon._restore import check_effects_state, check_times

log = logging.getLogger("gyrotherm.daemon")

#: Default sensor silence after which the next temperature frame is a power-on, s.
POWER_ON_GAP_S = 30.0
#: Temperatures a sensor can report when nothing else is known (no DBC limits), °C.
DEFAULT_TEMPERATURE_RANGE_C = (-60.0, 150.0)
_ZERO = (0.0, 0.0, 0.0)
_T, _DT = int(EffectFlags.T_CLAMPED), int(EffectFlags.DT_CLAMPED)
_T_ON, _SKIPPED = int(EffectFlags.T_ON_CLAMPED), int(EffectFlags.SKIPPED)


@dataclass(frozen=True)
class EffectsSnapshot:
    """What a restarted daemon needs to continue the effects: the power-on time and
    the time of the latest step on the sensor's clock (s), the compensator's
    :meth:`~Compensator.state_dict`."""

    power_on_s: float
    time_s: float
    state: dict[str, Any] | None
    """None: the effects state was dropped (out of bounds); the effects start afresh."""
    zero: dict[str, Any] | None = field(default=None)
    """:meth:`BootZero.to_dict` when a zero is configured, else None."""
    source: str = "saved effects state"
    """Where it was read (for the journal)."""


def _kept_running(since_saved_s: float, gap_s: float) -> bool:
    """The first frame continues a saved run within the gap, or nobody can tell (NaN);
    a frame further on, or a clock that restarted (negative), is a power cycle."""
    return math.isnan(since_saved_s) or 0.0 <= since_saved_s <= gap_s


def _same_kinds(a: Calibration, b: Calibration) -> bool:
    return a.axes == b.axes and all(a.effect_names(x) == b.effect_names(x) for x in a.axes)


class Compensation:
    """Bias and bias flags of the latest estimate; see the module docstring."""

    def __init__(self, calibration: Calibration | None, power_on_gap_s: float,
                 zero: ZeroConfig | None = None, *,
                 temperature_range_c: tuple[float, float] = DEFAULT_TEMPERATURE_RANGE_C
                 ) -> None:
        self.power_on_gap_s = power_on_gap_s
        self.temperature_range_c = temperature_range_c
        self._last_inputs: tuple[float, float, float, float] | None = None  # t, T, ΔT, t_on
        self._unusable: EffectsSnapshot | None = None  # a saved state not taken back
        self.zero = None if zero is None else BootZero(zero)
        self.calibration: Calibration | None = None
        self.compensator: Compensator | None = None
        self.power_on_s = math.nan
        self.time_s = math.nan  # time of the latest step, s
        self.t_on_s = math.nan  # t_on fed to the latest step, s
        self._cached: tuple[tuple[float, float, float], StatusFlags] | None = None
        self._restore: EffectsSnapshot | None = None
        self.power_on_listener: Callable[[float, bool, bool, bool, float], None] | None = None
        """Called at every power-on with (time_s, first, time_base, restored,
        receive_time_s): the ``[learn]`` mode (:mod:`gyrotherm.daemon._learner`)."""
        self.set_calibration(calibration)

    def set_calibration(self, calibration: Calibration | None) -> None:
        if calibration == self.calibration:
            return  # the same model: its state continues, nothing is stepped again
        old = self.compensator
        old_bias, last_inputs = self._cached, self._last_inputs
        self.calibration, self._cached, self._restore = calibration, None, None
        if calibration is None:
            self.compensator = None
        elif old is not None and _same_kinds(old.calibration, calibration):
            self.compensator = Compensator.load_state(calibration, old.state_dict())
            log.info("calibration changed: effects state taken over (same effects)")
        else:
            self.compensator = calibration.compensator()
            if old is not None:
                log.info("calibration changed: other effects, their state starts now")
        z = self.zero
        if z is None:
            return
        if calibration is None:
            z.stop()
        elif z.status == ZeroStatus.OFF:  # at the next rate frame; after the power-on
            z.start(trusted=math.isnan(self.power_on_s))  # the vehicle may be moving
        elif z.status == ZeroStatus.DONE:
            self._carry_zero(old_bias, last_inputs)
        elif z.status == ZeroStatus.PENDING:
            z.discard_window()  # the old model's residuals must not mix with the new's
        # FAILED stays failed

    def _carry_zero(self, old_bias: tuple[tuple[float, float, float], StatusFlags] | None,
                    inputs: tuple[float, float, float, float] | None) -> None:
        """z' = z + b_old − b_new (module docstring), b_new the new calibration at the very
        estimate b_old was computed at (on a copy of the new compensator: its own state is
        stepped by the pipeline as usual)."""
        z, comp = self.zero, self.compensator
        assert z is not None and comp is not None
        carried: tuple[float, ...] = ()
        if old_bias is not None and not old_bias[1] & StatusFlags.BIAS_INVALID and inputs:
            try:
                b = Compensator.load_state(comp.calibration, comp.state_dict()).step(*inputs)
                new = tuple(b.bias_dps.get(a, 0.0) for a in ("x", "y", "z"))
                if not b.flags & _SKIPPED:
                    carried = tuple(o + b0 - b1 for o, b0, b1 in zip(
                        z.offset_dps, old_bias[0], new, strict=True))
            except (ArithmeticError, ValueError):
                carried = ()
        limit = z.config.max_offset_dps
        if carried and all(math.isfinite(v) and abs(v) <= limit for v in carried):
            z.offset_dps = (carried[0], carried[1], carried[2])
            log.info("boot-time zero carried over to the new calibration (not measured "
                     "again): x %+.5f, y %+.5f, z %+.5f °/s", *carried)
            return
        log.warning("boot-time zero cannot be carried over (%s): measured again from now, "
                    "flagged ZERO_UNVERIFIED when taken",
                    "no valid bias of both calibrations at one estimate" if not carried else
                    ", ".join(f"{v:+.4g}" for v in carried) + f" °/s beyond max_offset_dps "
                    f"= {limit:g} °/s")
        z.start(trusted=False)

    def note_unusable_state(self, snapshot: EffectsSnapshot | None) -> None:
        """A saved state this daemon cannot take back (another calibration; or None: a file
        that could not be read). If the gyro kept running (the first frame continues the
        saved time within the gap; unknown for None) the vehicle may be moving: the zero
        starts untrusted, or stays failed if it had failed."""
        self._unusable = snapshot if snapshot is not None else EffectsSnapshot(
            math.nan, math.nan, None)

    def restore_at_power_on(self, snapshot: EffectsSnapshot) -> None:
        """Continue from ``snapshot`` if the first temperature frame continues it; its
        times and effects state are checked against their bounds first
        (:mod:`gyrotherm.daemon._restore`): what is out of bounds is dropped, with a
        warning, and never saved again."""
        problem = check_times(snapshot.power_on_s, snapshot.time_s)
        if problem:
            log.warning("%s ignored, starting from power-on: %s", snapshot.source, problem)
            self.note_unusable_state(None)
            return
        state = snapshot.state
        if state is not None and self.compensator is not None:
            try:
                check_effects_state(state, self.compensator.calibration,
                                    power_on_s=snapshot.power_on_s, time_s=snapshot.time_s,
                                    temperature_range_c=self.temperature_range_c,
                                    source=snapshot.source)
            except CalibrationError as exc:
                log.warning("effects state dropped (the effects start afresh; power-on time "
                            "and zero still restored): %s", exc)
                state = None
        self._restore = EffectsSnapshot(snapshot.power_on_s, snapshot.time_s, state,
                                        snapshot.zero, snapshot.source)

    def power_on(self, time_s: float, *, first: bool, time_base: bool = False,
                 receive_time_s: float = math.nan) -> None:
        """The gyro powered on at ``time_s`` (``first``: the daemon's first frame,
        where a saved state may be restored instead; ``time_base``: a time-base change,
        which may be a clock step as well as a reboot: the zero starts untrusted;
        ``receive_time_s``: the frame's wall-clock receive time, for the listener)."""
        snap, self._restore = self._restore, None
        if (first and snap is not None and self.compensator is not None
                and 0.0 <= time_s - snap.time_s <= self.power_on_gap_s):
            cal = self.compensator.calibration
            self.compensator = (cal.compensator() if snap.state is None else
                                Compensator.load_state(cal, snap.state, source=snap.source))
            self.power_on_s, self.time_s, self._cached = snap.power_on_s, snap.time_s, None
            log.info("effects state restored: power-on at %r s, t_on %.1f s%s", snap.power_on_s,
                     time_s - snap.power_on_s,
                     "" if snap.state is not None else " (effects state dropped)")
            if self.zero is not None:
                what = self.zero.restore(snap.zero, time_s, power_on_s=snap.power_on_s,
                                         saved_time_s=snap.time_s)
                log.log(logging.WARNING if "dropped" in what else logging.INFO,
                        "boot-time zero after the restart (%s): %s", snap.source, what)
            if self.power_on_listener is not None:
                self.power_on_listener(time_s, first, time_base, True, receive_time_s)
            return
        if first and snap is not None:
            log.info("saved effects state not restored: first frame at %r s does not continue "
                     "%r s within %g s; power-on now", time_s, snap.time_s, self.power_on_gap_s)
        unusable, self._unusable = self._unusable, None
        self.power_on_s, self._cached = time_s, None
        if self.compensator is not None:
            self.compensator.reset()
            z = self.zero
            if z is not None:
                if time_base:
                    z.start(time_s, trusted=False,
                            reference=z.offset_dps if z.status == ZeroStatus.DONE else None)
                elif first and unusable is not None and _kept_running(
                        time_s - unusable.time_s, self.power_on_gap_s):
                    # the gyro may have kept running (or nobody can tell): not a power-on
                    # the daemon can trust, and a zero that had failed stays failed
                    failed = (unusable.zero or {}).get("status") == "failed"
                    z.start(time_s, trusted=False)
                    if failed:
                        z.fail()
                    log.info("boot-time zero after a restart whose saved state was not taken "
                             "back: %s", "stays failed until the next power-on" if failed
                             else "measured again, flagged ZERO_UNVERIFIED when taken")
                else:
                    z.start(time_s)
        if self.power_on_listener is not None:
            self.power_on_listener(time_s, first, time_base, False, receive_time_s)

    def snapshot(self) -> EffectsSnapshot | None:
        """The state to persist, None before the first step."""
        c = self.compensator
        if c is None or math.isnan(self.time_s) or not c.last:
            return None
        return EffectsSnapshot(self.power_on_s, self.time_s, c.state_dict(),
                               None if self.zero is None else self.zero.to_dict())

    def bias(self, time_s: float, temperature_c: float, delta_t_c: float, *, step: bool
             ) -> tuple[tuple[float, float, float], StatusFlags]:
        """Bias (x, y, z) and flags at the latest estimate; ``step``: it is a new one
        (else the cached result, when there is one, is returned unchanged)."""
        c = self.compensator
        if c is None:
            return _ZERO, StatusFlags.NONE
        if not step and self._cached is not None:
            return self._cached
        self.time_s, self.t_on_s = time_s, time_s - self.power_on_s
        self._last_inputs = (time_s, temperature_c, delta_t_c, self.t_on_s)
        try:
            b = c.step(time_s, temperature_c, delta_t_c, self.t_on_s)
            bias = (b.bias_dps.get("x", 0.0), b.bias_dps.get("y", 0.0), b.bias_dps.get("z", 0.0))
            valid = not b.flags & _SKIPPED and all(math.isfinite(v) for v in bias)
        except (ArithmeticError, ValueError):  # x**p overflows; fsum(inf, -inf)
            valid = False
        flags = StatusFlags.NONE
        if valid:
            if b.flags & _T:
                flags |= StatusFlags.T_CLAMPED
            if b.flags & _DT:
                flags |= StatusFlags.DELTA_T_CLAMPED
            if b.flags & _T_ON:
                flags |= StatusFlags.T_ON_CLAMPED
        else:
            bias, flags = _ZERO, StatusFlags.BIAS_INVALID
        self._cached = (bias, flags)
        return self._cached

    def zero_state(self) -> ZeroState | None:
        """The boot-time zero for the state message; None when none is configured."""
        z = self.zero
        return None if z is None else ZeroState(int(z.status), z.offset_dps)

    def axis_effects(self) -> dict[str, AxisEffects]:
        """Per axis, the effects' state after the latest step (the state message's
        ``effects``); empty before a step or without a calibration."""
        c = self.compensator
        if c is None or not c.last or self._cached is None:
            return {}
        out = {}
        for axis, kernel in c.kernels.items():
            s, o = kernel.state, c.last[axis]
            if s.samples == 0:  # nothing accepted yet (every step skipped)
                out[axis] = AxisEffects(math.nan, math.nan, 0, self.t_on_s, math.nan)
            else:
                out[axis] = AxisEffects(s.structure_temperature_c, s.hysteresis_h,
                                        s.hysteresis_direction, self.t_on_s, o.bias_dps)
        return out
