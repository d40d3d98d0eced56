"""Nothing restored is trusted without its bounds: the saved effects state, checked
against the same physical bounds as live data before the daemon takes it back.

A state file (:mod:`gyrotherm.daemon._effects_store`) is parsed with bounded
numbers (:mod:`gyrotherm._safefile`) and a valid layout; this module checks what
the values *mean*, against the calibration now loaded and the sensor's DBC:

* **times**: ``power_on_s`` ≤ ``time_s`` (a power-on in the future of the latest
  step is impossible), t_on = ``time_s − power_on_s`` ≤ :data:`MAX_UPTIME_S`, and
  ``|time_s|`` ≤ 10¹² s (the pipeline's own stamp limit). Out of bounds: the
  whole state is dropped (nothing is known about this power cycle);
* **each axis' effects state** (:class:`~gyrotherm.compensation.Compensator`
  layout, validated by :meth:`~gyrotherm.compensation.Compensator.load_state`),
  for every axis that has accepted a sample: its ``time_s`` not after the saved
  ``time_s``, its ``power_on_s`` equal to the saved one (within
  :data:`POWER_ON_TOLERANCE_S`), every temperature (``structure_temperature_c``,
  ``hysteresis_high_c``/``low_c``) inside the sensor's range (the DBC
  temperature signal's [minimum, maximum]), hysteresis extremes around T_s
  (lo ≤ T_s ≤ hi) and travel ≤ 1000·w for an axis with ``hysteresis``, and
  ``samples`` ≤ 2⁵³. Out of bounds: the effects state is dropped (the effects
  start at the current estimate, as after a reload with other effects), the
  power-on time and the zero are still restored;
* the **boot-time zero**: checked by
  :meth:`~gyrotherm.compensation.BootZero.restore` (offset within this
  config's ``max_offset_dps``, times inside the saved run).

Every drop is one warning naming the file, the field, the value and the bound. A
dropped part is not restored, so it is never saved again.
"""

from __future__ import annotations

from typing import Any

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation import Calibration, Compensator
from gyrotherm.compensation._effects import MIN_TRANSITION_C

#: Longest time since power-on a saved state may claim, s (10 years).
MAX_UPTIME_S = 10 * 365.25 * 86400.0
#: |per-axis power_on_s − saved power_on_s| accepted (rounding of t − t_on), s.
POWER_ON_TOLERANCE_S = 1e-3
_MAX_ABS_TIME_S = 1e12
_MAX_SAMPLES = 2**53
_TRAVEL_CAP = 1000.0


def check_times(power_on_s: float, time_s: float) -> str:
    """Why the saved times are impossible (empty: they are plausible)."""
    if not abs(time_s) <= _MAX_ABS_TIME_S or not abs(power_on_s) <= _MAX_ABS_TIME_S:
        return f"time_s = {time_s!r} s or power_on_s = {power_on_s!r} s is beyond ±1e12 s"
    if power_on_s > time_s:
        return (f"power_on_s = {power_on_s!r} s is after the latest step time_s = "
                f"{time_s!r} s (a power-on in the future)")
    if time_s - power_on_s > MAX_UPTIME_S:
        return (f"power_on_s = {power_on_s!r} s puts the power-on {time_s - power_on_s:.4g} s "
                f"before the latest step, more than {MAX_UPTIME_S:.4g} s (10 years)")
    return ""


def check_effects_state(state: Any, calibration: Calibration, *, power_on_s: float,
                        time_s: float, temperature_range_c: tuple[float, float],
                        source: str) -> Compensator:
    """A compensator continuing ``state``, or CalibrationError naming ``source``, the
    axis, the field, its value and the bound (module docstring)."""
    comp = Compensator.load_state(calibration, state, source=source)
    lo, hi = temperature_range_c
    for axis, kernel in comp.kernels.items():
        s = kernel.state
        if s.samples == 0:
            continue
        where = f"{source}: field 'axes.{axis}"
        if s.samples > _MAX_SAMPLES:
            raise CalibrationError(f"{where}.samples' = {s.samples} is more than 2**53")
        if s.time_s > time_s:
            raise CalibrationError(f"{where}.time_s' = {s.time_s!r} s is after the saved "
                                   f"time_s = {time_s!r} s")
        if not abs(s.power_on_s - power_on_s) <= POWER_ON_TOLERANCE_S:
            raise CalibrationError(f"{where}.power_on_s' = {s.power_on_s!r} s disagrees with "
                                   f"the saved power_on_s = {power_on_s!r} s")
        for name in ("structure_temperature_c", "hysteresis_high_c", "hysteresis_low_c"):
            v = getattr(s, name)
            if not lo <= v <= hi:
                raise CalibrationError(f"{where}.{name}' = {v!r} °C is outside the sensor's "
                                       f"range [{lo:g}, {hi:g}] °C")
        hyst = calibration.effects_of(axis).hysteresis
        if hyst is not None:
            w = max(hyst.transition_c, MIN_TRANSITION_C)
            ts = s.structure_temperature_c
            if not s.hysteresis_low_c <= ts <= s.hysteresis_high_c:
                raise CalibrationError(
                    f"{where}': hysteresis extremes [{s.hysteresis_low_c!r}, "
                    f"{s.hysteresis_high_c!r}] °C do not contain structure_temperature_c = "
                    f"{ts!r} °C")
            if s.hysteresis_travel_c > _TRAVEL_CAP * w:
                raise CalibrationError(f"{where}.hysteresis_travel_c' = "
                                       f"{s.hysteresis_travel_c!r} °C is more than 1000·w = "
                                       f"{_TRAVEL_CAP * w:g} °C")
    return comp

