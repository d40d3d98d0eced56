"""The diagnosis' effects in online form: one stateful kernel, sample by sample.

The kernel is fed the estimator's output at each temperature update, (t, T, ΔT)
at irregular steps, plus t_on (time since the gyro powered on, from the
caller). It returns the *structure temperature* T_s at which the base
polynomial (the paper model, :class:`~gyrotherm.compensation.Calibration`) is
to be evaluated, the clamped ΔT, and the additive bias of the other effects.
Offline evaluation (:meth:`EffectsKernel.series`) loops the same
:meth:`EffectsKernel.step`. One kernel per axis: the diagnosis fits every axis
on its own, time constants included. Per accepted sample k (dt_k = t_k − t_(k−1)):

* ``thermal_lag`` (τ): T_s,k = T_s,k−1 + (1 − exp(−dt_k/τ))·(T_k − T_s,k−1),
  T_s,0 = T_0: the exact zero-order-hold discretisation of τ·dT_s/dt = T − T_s;
  on a uniform grid it is :func:`gyrotherm.analysis.lowpass`. Without it T_s = T.
  T_s replaces T in every temperature term (the paper's and ``cubic``).
* ``hysteresis`` (A, w = max(``transition_c``, 0.02 °C)): the play operator of
  :func:`gyrotherm.analysis.direction_state` on T_s: hi ← max(hi, T_s),
  lo ← min(lo, T_s); if d ≥ 0 and hi − T_s > w: d ← −1, lo ← T_s (falling is
  checked first: it wins ties); elif d ≤ 0 and T_s − lo > w: d ← +1, hi ← T_s.
  D = Σ|T_s,k − T_s,k−1| since the last flip (the flip sample's step included),
  h = d + (h₀ − d)·exp(−D/w), h₀ = h just before the flip; bias += A·h.
  State: d ∈ {−1, 0, +1}, hi, lo, D, h₀, h (start: d = h = h₀ = D = 0,
  hi = lo = T_s,0). D is capped at 1000·w, where exp(−D/w) is already 0.0.
* ``warmup`` (A, τ): bias += A·exp(−t_on/τ). State: the power-on time
  t_k − t_on,k, kept so that a restarted caller can go on counting t_on.
* ``cubic`` (c, T_ref): bias += c·(T_s − T_ref)³;
  ``gradient_quadratic`` (c): bias += c·ΔT². Stateless.
* ``correction`` (variable v, knots, values): bias += the linear spline of the values
  at the knots in v ∈ {T, ΔT (the estimator's, unclamped), t_on}, constant beyond
  the first and last knot (:mod:`._correction`: the diagnosis' ``unexplained``
  structure, deployed). Stateless.
* ``drift`` (s): bias += s·min(t_on, t_on_max)/3600, compensated from power-on
  as the diagnosis fits it. Open decision: a drift that is ageing rather than a
  per-power-on ramp would be extrapolated from the calibration date (wall-clock
  age instead of t_on), or only flagged (A = 0, report s·t_on/3600). Either
  changes only the time fed to this term; ``t_on_max_s`` (the longest
  calibration run) stops the ramp being extrapolated silently.

Contract (after PX4's ``TemperatureCompensation.h``): T, T_s and ΔT in °C,
t and t_on in s, biases in °/s, corrected rate = raw − (base(T̂_s, ΔT̂) + bias).
With a calibrated range, T̂_s = clamp(T_s, t_min_c, t_max_c) and
ΔT̂ = clamp(ΔT, dt_min_c, dt_max_c) feed the base polynomial, ``cubic`` and
``gradient_quadratic``; a clamp raises ``T_CLAMPED``/``DT_CLAMPED``. The state
evolves on the unclamped T_s (the structure's temperature is physical; h is
bounded by 1 anyway). t_on < 0 is taken as 0, t_on > t_on_max as t_on_max
(``T_ON_CLAMPED``). A sample whose t or t_on is not finite or beyond ±1e12 s,
or whose T or ΔT is not finite or beyond ±1e4 °C, is skipped: the state is
untouched and the previous output is returned with ``SKIPPED`` (before any
accepted sample: T_s = ΔT = NaN, bias 0). Time running backwards counts as
dt = 0 (``TIME_REVERSED``) and re-bases the clock: every state value stays
finite whatever the inputs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._correction import Correction
from gyrotherm.compensation._effects_state import (
    EffectFlags,
    EffectsOutput,
    EffectsSeries,
    EffectsState,
    InputRange,
)

FloatArray = NDArray[np.float64]
#: Smallest hysteresis transition (dead band and saturation), °C (as the diagnosis).
MIN_TRANSITION_C = 0.02
#: Largest |T| and |ΔT| accepted as a reading, °C; largest |t| and |t_on|, s.
INPUT_LIMIT_C = 1e4
TIME_LIMIT_S = 1e12
_TRAVEL_CAP = 1000.0


@dataclass(frozen=True)
class _Params:
    """Parameters of one effect: finite numbers, ``_positive`` ones > 0 (None: unset)."""

    _positive: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None:
                continue
            if not (isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)):
                raise CalibrationError(f"{type(self).__name__}.{f.name}: expected a finite "
                                       f"number, got {v!r}")
            if f.name in self._positive and not v > 0:
                raise CalibrationError(f"{type(self).__name__}.{f.name}: must be > 0, got {v!r}")


@dataclass(frozen=True)
class ThermalLag(_Params):
    """T_s lags T with time constant ``tau_s``."""

    tau_s: float
    _positive = ("tau_s",)


@dataclass(frozen=True)
class Hysteresis(_Params):
    """bias += ``amplitude_dps``·h, h saturating over ``transition_c`` of travel."""

    amplitude_dps: float
    transition_c: float
    _positive = ("transition_c",)


@dataclass(frozen=True)
class Warmup(_Params):
    """bias += ``amplitude_dps``·exp(−t_on/``tau_s``)."""

    amplitude_dps: float
    tau_s: float
    _positive = ("tau_s",)


@dataclass(frozen=True)
class Cubic(_Params):
    """bias += ``coefficient_dps_per_c3``·(T̂_s − ``t_ref_c``)³."""

    coefficient_dps_per_c3: float
    t_ref_c: float


@dataclass(frozen=True)
class GradientQuadratic(_Params):
    """bias += ``coefficient_dps_per_c2``·ΔT̂²."""

    coefficient_dps_per_c2: float


@dataclass(frozen=True)
class Drift(_Params):
    """bias += ``slope_dps_per_h``·min(t_on, ``t_on_max_s``)/3600; ``t_on_max_s``: the
    longest time since power-on calibrated (None: the ramp is not limited)."""

    slope_dps_per_h: float
    t_on_max_s: float | None = None
    _positive = ("t_on_max_s",)


_KINDS: dict[str, type] = {
    "thermal_lag": ThermalLag, "hysteresis": Hysteresis, "warmup": Warmup,
    "cubic": Cubic, "gradient_quadratic": GradientQuadratic, "drift": Drift,
    "correction": Correction,
}


@dataclass(frozen=True)
class Effects:
    """The effects of one axis (None: absent), in the diagnosis' order."""

    thermal_lag: ThermalLag | None = None
    hysteresis: Hysteresis | None = None
    warmup: Warmup | None = None
    cubic: Cubic | None = None
    gradient_quadratic: GradientQuadratic | None = None
    drift: Drift | None = None
    correction: Correction | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n in _KINDS if getattr(self, n) is not None)

    @classmethod
    def from_params(
        cls, params: Mapping[str, Mapping[str, Any]], *, t_ref_c: float | None = None
    ) -> Effects:
        """From ``{effect: {parameter: value}}`` (:meth:`ExtendedModel.params` layout);
        ``t_ref_c`` fills a ``cubic`` without one (the model's scaling.t_ref_c)."""
        out: dict[str, Any] = {}
        for name, values in params.items():
            kind = _KINDS.get(name)
            if kind is None:
                raise CalibrationError(f"unknown effect {name!r}; known: {', '.join(_KINDS)}")
            values = dict(values)
            if name == "cubic" and "t_ref_c" not in values and t_ref_c is not None:
                values["t_ref_c"] = t_ref_c
            try:
                out[name] = kind(**values)
            except TypeError as exc:
                want = [f.name for f in fields(kind)]
                raise CalibrationError(f"effect {name!r}: parameters {sorted(values)}, "
                                       f"expected {want}") from exc
        return cls(**out)

    def to_params(self) -> dict[str, dict[str, Any]]:
        """Inverse of :meth:`from_params` (a correction's knots and values as lists)."""
        out = {n: asdict(getattr(self, n)) for n in self.names}
        if self.correction is not None:
            out["correction"] = self.correction.to_dict()
        return out


_NO_OUTPUT = EffectsOutput(math.nan, math.nan, 0.0, 0)
_SKIPPED, _REVERSED = int(EffectFlags.SKIPPED), int(EffectFlags.TIME_REVERSED)
_T_CLAMPED, _DT_CLAMPED = int(EffectFlags.T_CLAMPED), int(EffectFlags.DT_CLAMPED)
_T_ON_CLAMPED = int(EffectFlags.T_ON_CLAMPED)


class EffectsKernel:
    """Online effects of one axis; see the module docstring for the maths.

    ``limits``: the calibrated T/ΔT range (None: no clamping, as the diagnosis
    evaluates). ``state``: continue from it (used in place, not copied).
    """

    def __init__(self, effects: Effects, limits: InputRange | None = None,
                 state: EffectsState | None = None) -> None:
        self.effects = effects
        self.limits = limits
        self.state = state if state is not None else EffectsState()
        e = effects
        self._lag = e.thermal_lag.tau_s if e.thermal_lag else 0.0
        self._hyst_a = e.hysteresis.amplitude_dps if e.hysteresis else 0.0
        self._w = max(e.hysteresis.transition_c, MIN_TRANSITION_C) if e.hysteresis else 0.0
        self._t_range = (limits.t_min_c, limits.t_max_c) if limits else (-math.inf, math.inf)
        self._dt_range = (limits.dt_min_c, limits.dt_max_c) if limits else (-math.inf, math.inf)
        self._last = _NO_OUTPUT

    def reset(self) -> None:
        """Forget the history (a power cycle of the gyro)."""
        self.state.reset()
        self._last = _NO_OUTPUT

    def step(self, time_s: float, temperature_c: float, delta_t_c: float,
             t_on_s: float) -> EffectsOutput:
        """Advance by one estimator output (t, T, ΔT) with the caller's t_on (s since
        power-on); pure-Python floats, O(1). 1 − exp(−dt/τ) is computed as
        −expm1(−dt/τ), which keeps its digits at 100 Hz with τ of an hour."""
        if not (abs(time_s) <= TIME_LIMIT_S and abs(t_on_s) <= TIME_LIMIT_S
                and abs(temperature_c) <= INPUT_LIMIT_C and abs(delta_t_c) <= INPUT_LIMIT_C):
            last = self._last
            self._last = last._replace(flags=last.flags | _SKIPPED)
            return self._last
        s = self.state
        flags = 0
        if s.samples == 0:
            prev = ts = temperature_c
            s.hysteresis_high_c = s.hysteresis_low_c = ts
            s.hysteresis_direction = 0
            s.hysteresis_h = s.hysteresis_h_start = s.hysteresis_travel_c = 0.0
        else:
            prev = s.structure_temperature_c
            dt = time_s - s.time_s
            if dt < 0.0:
                flags |= _REVERSED
                dt = 0.0
            if self._lag:
                ts = prev - math.expm1(-dt / self._lag) * (temperature_c - prev)
            else:
                ts = temperature_c
        s.samples += 1
        s.time_s = time_s
        s.power_on_s = time_s - t_on_s
        s.structure_temperature_c = ts
        e = self.effects
        bias = 0.0
        if self._w:
            bias += self._hyst_a * self._hysteresis(s, ts, abs(ts - prev))
        lo, hi = self._t_range
        tc = min(max(ts, lo), hi)
        lo, hi = self._dt_range
        dc = min(max(delta_t_c, lo), hi)
        if tc != ts:
            flags |= _T_CLAMPED
        if dc != delta_t_c:
            flags |= _DT_CLAMPED
        t_on = t_on_s
        if t_on < 0.0:
            t_on = 0.0
            flags |= _T_ON_CLAMPED
        if e.warmup is not None:
            bias += e.warmup.amplitude_dps * math.exp(-t_on / e.warmup.tau_s)
        if e.cubic is not None:
            bias += e.cubic.coefficient_dps_per_c3 * (tc - e.cubic.t_ref_c) ** 3
        if e.gradient_quadratic is not None:
            bias += e.gradient_quadratic.coefficient_dps_per_c2 * dc * dc
        if e.correction is not None:
            c = e.correction
            bias += c.value(temperature_c if c.variable == "temperature_c" else
                            delta_t_c if c.variable == "delta_t_c" else t_on)
        if e.drift is not None:
            top = e.drift.t_on_max_s
            if top is not None and t_on > top:
                t_on = top
                flags |= _T_ON_CLAMPED
            bias += e.drift.slope_dps_per_h * (t_on / 3600.0)
        self._last = EffectsOutput(tc, dc, bias, flags)
        return self._last

    def _hysteresis(self, s: EffectsState, ts: float, step_c: float) -> float:
        """The play operator and h's saturation (module docstring); returns h."""
        w = self._w
        hi = s.hysteresis_high_c if s.hysteresis_high_c > ts else ts
        lo = s.hysteresis_low_c if s.hysteresis_low_c < ts else ts
        d = s.hysteresis_direction
        if d >= 0 and hi - ts > w:
            d, lo, travel = -1, ts, step_c
            s.hysteresis_h_start = s.hysteresis_h
        elif d <= 0 and ts - lo > w:
            d, hi, travel = 1, ts, step_c
            s.hysteresis_h_start = s.hysteresis_h
        else:
            travel = s.hysteresis_travel_c + step_c
        travel = min(travel, _TRAVEL_CAP * w)
        h = d + (s.hysteresis_h_start - d) * math.exp(-travel / w)
        s.hysteresis_high_c, s.hysteresis_low_c, s.hysteresis_direction = hi, lo, d
        s.hysteresis_travel_c, s.hysteresis_h = travel, h
        return h

    def series(self, time_s: FloatArray, temperature_c: FloatArray, delta_t_c: FloatArray,
               t_on_s: FloatArray | None = None) -> EffectsSeries:
        """:meth:`step` over arrays, continuing from the current state;
        ``t_on_s`` defaults to ``time_s`` (run files count from power-on)."""
        cols = [np.asarray(c, dtype=np.float64).tolist()
                for c in (time_s, temperature_c, delta_t_c,
                          time_s if t_on_s is None else t_on_s)]
        if len({len(c) for c in cols}) != 1:
            raise ValueError(f"series: lengths differ {[len(c) for c in cols]}")
        rows = [self.step(*r) for r in zip(*cols, strict=True)]
        out = np.array(rows, dtype=np.float64).reshape(len(rows), 4)
        return EffectsSeries(out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy(),
                             out[:, 3].astype(np.int64))
