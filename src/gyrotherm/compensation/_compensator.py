"""Per-axis online compensation: the base polynomial at the effects kernel's outputs.

A :class:`Compensator` holds one :class:`~gyrotherm.compensation._effects.EffectsKernel`
per axis of a :class:`~gyrotherm.compensation.Calibration` (limits = the
calibrated range, effects = the calibration's for that axis; none for a
version-1 file). Each step feeds every kernel the estimator's (t, T, ΔT) and
t_on, evaluates the calibration's base polynomial at the kernel's clamped
structure temperature T̂_s and ΔT̂ (:meth:`Calibration.base_bias`), adds the
kernel's bias and merges the kernels' :class:`EffectFlags`:

    bias_axis = base_axis(T̂_s,axis, ΔT̂) + effects_axis

Without effects T̂_s = clamp(T) and the effects' bias is 0.0, so a step equals
:meth:`Calibration.bias_at` bit for bit. Before the first accepted sample (or
after only skipped ones) T̂_s is NaN: the bias is NaN and ``SKIPPED`` is set.
:meth:`Compensator.series` loops the same kernels' ``step`` (continuing their
state) and evaluates the polynomial on the arrays (:meth:`Calibration.base_series`,
equal to the scalar form to rounding).

t_on (s since the gyro powered on) defaults to t: run files count from power-on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._effects import EffectsKernel
from gyrotherm.compensation._effects_state import (
    STATE_VERSION,
    EffectFlags,
    EffectsOutput,
    EffectsState,
)

if TYPE_CHECKING:
    from gyrotherm.compensation._calibration import BiasEstimate, Calibration

FloatArray = NDArray[np.float64]
_T, _DT = int(EffectFlags.T_CLAMPED), int(EffectFlags.DT_CLAMPED)


@dataclass(frozen=True)
class CompensatedSeries:
    """:meth:`Compensator.series`: per axis, the bias (°/s) and the kernel's flags per row."""

    bias_dps: Mapping[str, FloatArray]
    flags: Mapping[str, NDArray[np.int64]]

    def clamped(self, axis: str) -> NDArray[np.bool_]:
        """Rows where T or ΔT was clamped to the calibrated range on ``axis``."""
        return np.asarray(self.flags[axis] & (_T | _DT) != 0)


class Compensator:
    """Online bias of every axis of ``calibration``; ``states``: per-axis kernel states
    to continue from (used in place), e.g. restored with :meth:`load_state`."""

    def __init__(self, calibration: Calibration,
                 states: Mapping[str, EffectsState] | None = None) -> None:
        self.calibration = calibration
        states = states or {}
        unknown = set(states) - set(calibration.axes)
        if unknown:
            raise CalibrationError(f"compensator: states for axes {sorted(unknown)} not in "
                                   f"the calibration (axes {list(calibration.axes)})")
        self.kernels = {a: EffectsKernel(calibration.effects_of(a), calibration.valid_range,
                                         states.get(a)) for a in calibration.axes}
        self.last: dict[str, EffectsOutput] = {}
        """Per axis, the kernel's output of the latest :meth:`step` (empty before one)."""

    def reset(self) -> None:
        """Forget every axis' history (a power cycle of the gyro)."""
        for k in self.kernels.values():
            k.reset()
        self.last = {}

    def step(self, time_s: float, temperature_c: float, delta_t_c: float,
             t_on_s: float | None = None) -> BiasEstimate:
        """Bias per axis for one estimator output; ``flags``: the kernels' flags merged."""
        from gyrotherm.compensation._calibration import BiasEstimate

        t_on = time_s if t_on_s is None else t_on_s
        cal = self.calibration
        # every kernel steps first: a polynomial that raises (overflow) leaves no axis behind
        self.last = out = {a: k.step(time_s, temperature_c, delta_t_c, t_on)
                           for a, k in self.kernels.items()}
        bias: dict[str, float] = {}
        flags = 0
        for axis, o in out.items():
            bias[axis] = cal.base_bias(axis, o.structure_temperature_c, o.delta_t_c) + o.bias_dps
            flags |= o.flags
        return BiasEstimate(bias, bool(flags & _T), bool(flags & _DT), flags)

    def series(self, time_s: FloatArray, temperature_c: FloatArray, delta_t_c: FloatArray,
               t_on_s: FloatArray | None = None) -> CompensatedSeries:
        """:meth:`step` over arrays (continuing the state), one row per sample."""
        cal = self.calibration
        bias: dict[str, FloatArray] = {}
        flags: dict[str, NDArray[np.int64]] = {}
        for axis, kernel in self.kernels.items():
            out = kernel.series(time_s, temperature_c, delta_t_c, t_on_s)
            base = cal.base_series(axis, out.structure_temperature_c, out.delta_t_c)
            bias[axis] = base + out.bias_dps
            flags[axis] = out.flags
        return CompensatedSeries(bias, flags)

    def state_dict(self) -> dict[str, Any]:
        """``{"version": 1, "axes": {axis: EffectsState.to_dict()}}``: JSON/msgpack-safe."""
        return {"version": STATE_VERSION,
                "axes": {a: k.state.to_dict() for a, k in self.kernels.items()}}

    @classmethod
    def load_state(cls, calibration: Calibration, data: Any, *,
                   source: str = "compensator state") -> Compensator:
        """A compensator continuing from :meth:`state_dict`'s output (validated)."""
        if not isinstance(data, dict) or data.get("version") != STATE_VERSION:
            raise CalibrationError(f"{source}: expected an object with 'version': "
                                   f"{STATE_VERSION}, got {data!r:.80}")
        axes = data.get("axes")
        if not isinstance(axes, dict) or set(axes) != set(calibration.axes):
            got = sorted(axes) if isinstance(axes, dict) else axes
            raise CalibrationError(f"{source}: field 'axes': expected the calibration's axes "
                                   f"{list(calibration.axes)}, got {got!r}")
        states = {a: EffectsState.from_dict(v, source=f"{source}: field 'axes.{a}'")
                  for a, v in axes.items()}
        return cls(calibration, states)
