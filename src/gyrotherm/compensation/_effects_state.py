"""Run-time state, inputs and outputs of the online effects kernel (``_effects``).

Plain Python ints and floats only, so that :meth:`EffectsState.to_dict` is safe
for JSON (persistence across daemon restarts) and msgpack (the wire), and a
round trip through either is bit-exact (both keep IEEE doubles; JSON via the
shortest round-trip repr). Every float is finite whatever the kernel was fed.

Fields (unit):

* ``samples`` (—): samples accepted since the last reset; 0: none, the rest unset;
* ``time_s`` (s): time of the last accepted sample, on the caller's clock;
* ``power_on_s`` (s): the power-on time on that clock, t − t_on of that sample;
* ``structure_temperature_c`` (°C): T_s, the lagged temperature (T without a lag);
* ``hysteresis_direction`` (—): d ∈ {−1, 0, +1}, the direction of the last move;
* ``hysteresis_high_c``, ``hysteresis_low_c`` (°C): hi and lo, the extremes of
  T_s since the last flip (or the start);
* ``hysteresis_travel_c`` (°C): D = Σ|ΔT_s| since the last flip (≤ 1000·w);
* ``hysteresis_h_start`` (—): h₀, h just before the last flip;
* ``hysteresis_h`` (—): h ∈ [−1, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from enum import IntFlag
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError

FloatArray = NDArray[np.float64]
STATE_VERSION = 1
_INTS = ("samples", "hysteresis_direction")


@dataclass(slots=True)
class EffectsState:
    """Mutable state of one axis' kernel; see the module docstring for the fields."""

    samples: int = 0
    time_s: float = 0.0
    power_on_s: float = 0.0
    structure_temperature_c: float = 0.0
    hysteresis_direction: int = 0
    hysteresis_high_c: float = 0.0
    hysteresis_low_c: float = 0.0
    hysteresis_travel_c: float = 0.0
    hysteresis_h_start: float = 0.0
    hysteresis_h: float = 0.0

    def reset(self) -> None:
        """Back to the state before any sample."""
        for f in fields(self):
            setattr(self, f.name, f.default)

    def time_on_s(self, time_s: float) -> float:
        """t_on at ``time_s`` on the same clock, from the stored power-on time."""
        return time_s - self.power_on_s

    def to_dict(self) -> dict[str, int | float]:
        out: dict[str, int | float] = {"version": STATE_VERSION}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = int(v) if f.name in _INTS else float(v)
        return out

    @classmethod
    def from_dict(cls, data: Any, *, source: str = "effects state") -> EffectsState:
        """Validate and load :meth:`to_dict`'s output; CalibrationError names the field."""
        if not isinstance(data, dict):
            raise CalibrationError(f"{source}: expected an object, got {type(data).__name__}")
        if data.get("version") != STATE_VERSION:
            raise CalibrationError(f"{source}: field 'version': expected {STATE_VERSION}, "
                                   f"got {data.get('version')!r}")
        names = [f.name for f in fields(cls)]
        extra = set(data) - {"version", *names}
        if extra:
            raise CalibrationError(f"{source}: unknown fields {sorted(extra)}")
        values: dict[str, int | float] = {}
        for name in names:
            if name not in data:
                raise CalibrationError(f"{source}: missing field {name!r}")
            v = data[name]
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise CalibrationError(f"{source}: field {name!r}: expected a number, got {v!r}")
            if name in _INTS:
                if not isinstance(v, int):
                    raise CalibrationError(f"{source}: field {name!r}: expected an integer, "
                                           f"got {v!r}")
                values[name] = v
            else:
                try:
                    values[name] = float(v)
                except OverflowError:
                    raise CalibrationError(f"{source}: field {name!r}: too large") from None
                if not math.isfinite(values[name]):
                    raise CalibrationError(f"{source}: field {name!r}: not finite ({v!r})")
        state = cls(**values)  # type: ignore[arg-type]
        problems = []
        if state.samples < 0:
            problems.append("'samples' < 0")
        if state.hysteresis_direction not in (-1, 0, 1):
            problems.append("'hysteresis_direction' not in {-1, 0, 1}")
        if state.hysteresis_travel_c < 0.0:
            problems.append("'hysteresis_travel_c' < 0")
        if not (abs(state.hysteresis_h) <= 1.0 and abs(state.hysteresis_h_start) <= 1.0):
            problems.append("|'hysteresis_h'| or |'hysteresis_h_start'| > 1")
        if state.hysteresis_low_c > state.hysteresis_high_c and state.samples:
            problems.append("'hysteresis_low_c' > 'hysteresis_high_c'")
        if problems:
            raise CalibrationError(f"{source}: {'; '.join(problems)}")
        return state


class InputRange(Protocol):
    """Calibrated input ranges, °C (:class:`~gyrotherm.compensation.ValidRange`)."""

    @property
    def t_min_c(self) -> float: ...
    @property
    def t_max_c(self) -> float: ...
    @property
    def dt_min_c(self) -> float: ...
    @property
    def dt_max_c(self) -> float: ...


class EffectFlags(IntFlag):
    """What a step did besides the plain evaluation (bits of ``EffectsOutput.flags``)."""

    NONE = 0
    SKIPPED = 1
    """Non-finite or implausible input: state untouched, previous output held."""
    TIME_REVERSED = 2
    T_CLAMPED = 4
    DT_CLAMPED = 8
    T_ON_CLAMPED = 16


class EffectsOutput(NamedTuple):
    """One step's result: the base polynomial's inputs and the effects' bias."""

    structure_temperature_c: float
    """T̂_s: the (clamped) temperature the base polynomial is evaluated at, °C."""
    delta_t_c: float
    """ΔT̂: the (clamped) gradient, °C."""
    bias_dps: float
    """Sum of the additive effects (not the base polynomial), °/s."""
    flags: int
    """:class:`EffectFlags` bits."""


@dataclass(frozen=True)
class EffectsSeries:
    """:meth:`EffectsKernel.series`: one row per input sample."""

    structure_temperature_c: FloatArray
    delta_t_c: FloatArray
    bias_dps: FloatArray
    flags: NDArray[np.int64]
