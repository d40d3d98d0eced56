"""Calibrations that cannot hurt: a physical plausibility check of a whole model.

A calibration file is data from outside the daemon. Every number in it being
finite (the parsers' check) does not make it safe: a hysteresis amplitude of
1e6 °/s, a drift of 1e6 °/s/h or a lag τ of 1e300 s are finite, and the
daemon would subtract them from the gyro's rate under clean flags. Before a
calibration is used (read from a file at start or on SIGHUP, or written by
``fit``), :func:`check_plausible` bounds what it can ever subtract.

**The bound.** The daemon evaluates the base polynomial at the *clamped*
inputs (T̂_s, ΔT̂ inside ``range``), and every effect's contribution is bounded
over the states it can reach (docs/model.md §6, module ``_effects``):

====================  ===========================================================
part                  largest |bias| it can add, °/s
====================  ===========================================================
base polynomial       max over the valid T × ΔT box (exact: :func:`_base_max_exact`)
``hysteresis``        \\|A\\| (h ∈ [−1, 1])
``warmup``            \\|A\\| (t_on ≥ 0: exp(−t_on/τ) ≤ 1)
``cubic``             \\|c\\|·max(\\|t_min − T_ref\\|, \\|t_max − T_ref\\|)³ (T̂_s clamped)
``gradient_quadratic`` \\|c\\|·max(dt_min², dt_max²) (ΔT̂ clamped)
``drift``             \\|s\\|·t_on_max/3600 (no ``t_on_max_s``: at
                      :data:`DRIFT_HORIZON_S`, one day since power-on)
``correction``        max \\|values_dps\\| (a linear spline between its knots)
====================  ===========================================================

Each part alone, and their sum per axis (the worst case of all reached together),
must stay within ``max_bias_dps`` (default :data:`MAX_BIAS_DPS` = 30 °/s: a MEMS
gyro's whole zero-rate offset over temperature is a few °/s; tens of °/s is a
broken fit or a hostile file). Time constants must be physical
(:data:`TAU_RANGE_S`), a hysteresis transition at most the calibrated span, the
valid range inside :data:`TEMPERATURE_LIMITS_C` and :data:`GRADIENT_LIMIT_C`.

A refusal is a :class:`~gyrotherm.CalibrationError` naming the axis, the effect
(or ``base polynomial``), the parameter, its value and the bound.
"""

from __future__ import annotations

import math

import numpy as np

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._calibration import Calibration
from gyrotherm.compensation._effects import Effects

#: Largest |bias| a calibration may predict anywhere it can be evaluated, °/s.
MAX_BIAS_DPS = 30.0
#: Physical time constants (thermal lag, warm-up), s: 1 ms … 1 day.
TAU_RANGE_S = (1e-3, 86400.0)
#: Time since power-on at which an unlimited drift ramp is bounded, s.
DRIFT_HORIZON_S = 86400.0
#: Longest ``drift.t_on_max_s`` accepted, s (30 days).
T_ON_MAX_LIMIT_S = 30 * 86400.0
#: A valid temperature range must lie inside this, °C.
TEMPERATURE_LIMITS_C = (-100.0, 200.0)
#: |ΔT| range limit, °C.
GRADIENT_LIMIT_C = 1000.0
_GRID = 65


def _refuse(axis: str, part: str, detail: str) -> CalibrationError:
    return CalibrationError(f"axis {axis!r}, {part}: {detail}")


def _base_max(cal: Calibration, axis: str) -> float:
    """max |base polynomial| over the valid T × ΔT box: exact for the shipped models
    (:func:`_base_max_exact`), else on a :data:`_GRID`² grid."""
    if all(t.t_power <= 3 and t.dt_power <= 1 for t in cal.model.terms):
        return _base_max_exact(cal, axis)
    return _base_max_grid(cal, axis)


def _base_max_exact(cal: Calibration, axis: str) -> float:
    """The exact maximum for a polynomial of degree ≤ 3 in T and ≤ 1 in ΔT (``paper``,
    ``t2``, ``t3``), in plain floats. For a fixed T it is linear in ΔT, so |bias| is
    largest at one of the box's two ΔT ends; at each, a polynomial p(x) of degree ≤ 3 in
    x = (T − T_ref)/s is largest in magnitude at an end of the T range or where p′ = 0.
    Evaluated with :meth:`Calibration.base_bias`. No numpy: the daemon checks every
    calibration it loads, and numpy's array code paged in for a grid stays resident
    (≈ 0.7 MB of the daemon's memory, ``bench/footprint.py``)."""
    r, s = cal.valid_range, cal.scaling
    coef = cal.coefficients[axis]
    x_lo = (r.t_min_c - s.t_ref_c) / s.t_scale_c
    x_hi = (r.t_max_c - s.t_ref_c) / s.t_scale_c
    best = 0.0
    try:
        for dt in (r.dt_min_c, r.dt_max_c):
            g = dt / s.dt_scale_c
            a = [0.0, 0.0, 0.0, 0.0]  # p(x) = a0 + a1 x + a2 x² + a3 x³ at this ΔT
            for term, c in zip(cal.model.terms, coef, strict=True):
                a[term.t_power] += c * g ** term.dt_power
            for x in (x_lo, x_hi, *(x for x in _stationary(a) if x_lo < x < x_hi)):
                v = cal.base_bias(axis, s.t_ref_c + x * s.t_scale_c, dt)
                if not math.isfinite(v):
                    return math.inf
                best = max(best, abs(v))
    except (OverflowError, ValueError):  # a coefficient so large the sums overflow
        return math.inf
    return best


def _stationary(a: list[float]) -> list[float]:
    """Real roots of p′(x) = a1 + 2 a2 x + 3 a3 x²."""
    q, b, c = 3.0 * a[3], 2.0 * a[2], a[1]
    if q == 0.0:
        return [-c / b] if b != 0.0 else []
    disc = b * b - 4.0 * q * c
    if disc < 0.0:
        return []
    root = math.sqrt(disc)
    return [(-b - root) / (2.0 * q), (-b + root) / (2.0 * q)]


def _base_max_grid(cal: Calibration, axis: str) -> float:
    r = cal.valid_range
    t = np.linspace(r.t_min_c, r.t_max_c, _GRID)
    d = np.linspace(r.dt_min_c, r.dt_max_c, _GRID)
    tt, dd = np.meshgrid(t, d)
    with np.errstate(all="ignore"):
        b = cal.base_series(axis, tt.ravel(), dd.ravel())
    return float(np.max(np.abs(b))) if np.all(np.isfinite(b)) else math.inf


def _effect_parts(cal: Calibration, axis: str, e: Effects) -> list[tuple[str, str, float, str]]:
    """(effect, parameter, |bias| bound °/s, how) per effect of one axis; time-constant
    problems raise at once."""
    r = cal.valid_range
    lo, hi = TAU_RANGE_S
    parts: list[tuple[str, str, float, str]] = []
    for name, tau in (("thermal_lag", e.thermal_lag.tau_s if e.thermal_lag else None),
                      ("warmup", e.warmup.tau_s if e.warmup else None)):
        if tau is not None and not lo <= tau <= hi:
            raise _refuse(axis, f"effect {name!r}", f"parameter 'tau_s' = {tau!r} s is outside "
                          f"the physical range [{lo:g}, {hi:g}] s")
    if e.hysteresis is not None:
        span = max(r.t_max_c - r.t_min_c, 1.0)
        w = e.hysteresis.transition_c
        if w > span:
            raise _refuse(axis, "effect 'hysteresis'", f"parameter 'transition_c' = {w!r} °C "
                          f"is wider than the calibrated span {span:g} °C")
        parts.append(("hysteresis", "amplitude_dps", abs(e.hysteresis.amplitude_dps), "|A|"))
    if e.warmup is not None:
        parts.append(("warmup", "amplitude_dps", abs(e.warmup.amplitude_dps), "|A|"))
    if e.cubic is not None:
        reach = max(abs(r.t_min_c - e.cubic.t_ref_c), abs(r.t_max_c - e.cubic.t_ref_c))
        parts.append(("cubic", "coefficient_dps_per_c3",
                      abs(e.cubic.coefficient_dps_per_c3) * reach**3,
                      f"|c|·{reach:g}³ (°C, T clamped to the range)"))
    if e.gradient_quadratic is not None:
        reach = max(abs(r.dt_min_c), abs(r.dt_max_c))
        parts.append(("gradient_quadratic", "coefficient_dps_per_c2",
                      abs(e.gradient_quadratic.coefficient_dps_per_c2) * reach**2,
                      f"|c|·{reach:g}² (°C, ΔT clamped to the range)"))
    if e.correction is not None:
        parts.append(("correction", "values_dps", e.correction.max_abs_dps, "max |values|"))
    if e.drift is not None:
        top = e.drift.t_on_max_s
        if top is not None and top > T_ON_MAX_LIMIT_S:
            raise _refuse(axis, "effect 'drift'", f"parameter 't_on_max_s' = {top!r} s is "
                          f"more than {T_ON_MAX_LIMIT_S:g} s")
        horizon = DRIFT_HORIZON_S if top is None else top
        parts.append(("drift", "slope_dps_per_h", abs(e.drift.slope_dps_per_h) * horizon / 3600,
                      f"|s|·{horizon:g} s/3600" + (" (no t_on_max_s: one day)"
                                                    if top is None else "")))
    return parts


def check_plausible(cal: Calibration, *, max_bias_dps: float = MAX_BIAS_DPS) -> None:
    """CalibrationError when ``cal`` can predict more than ``max_bias_dps`` anywhere it
    can be evaluated, or has unphysical ranges or time constants (module docstring)."""
    r = cal.valid_range
    tlo, thi = TEMPERATURE_LIMITS_C
    if not (tlo <= r.t_min_c and r.t_max_c <= thi):
        raise CalibrationError(f"range: temperature [{r.t_min_c:g}, {r.t_max_c:g}] °C is "
                               f"outside [{tlo:g}, {thi:g}] °C")
    if max(abs(r.dt_min_c), abs(r.dt_max_c)) > GRADIENT_LIMIT_C:
        raise CalibrationError(f"range: ΔT [{r.dt_min_c:g}, {r.dt_max_c:g}] °C is outside "
                               f"±{GRADIENT_LIMIT_C:g} °C")
    for axis in cal.axes:
        base = _base_max(cal, axis)
        if not base <= max_bias_dps:
            raise _refuse(axis, "base polynomial", f"|bias| reaches {base:.4g} °/s over the "
                          f"valid range, more than the {max_bias_dps:g} °/s bound")
        total, what = base, [f"base {base:.3g}"]
        for name, param, bound, how in _effect_parts(cal, axis, cal.effects_of(axis)):
            if not bound <= max_bias_dps:
                raise _refuse(axis, f"effect {name!r}", f"parameter {param!r} gives |bias| "
                              f"up to {bound:.4g} °/s ({how}), more than the "
                              f"{max_bias_dps:g} °/s bound")
            total += bound
            what.append(f"{name} {bound:.3g}")
        if not total <= max_bias_dps:
            raise _refuse(axis, "whole model", f"|bias| can reach {total:.4g} °/s "
                          f"({' + '.join(what)}), more than the {max_bias_dps:g} °/s bound")
