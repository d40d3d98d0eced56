"""Candidate physical effects: regressors of the bias model and simulator add-ons.

Every effect extends the paper model's design matrix (terms x², x, g, x·g in
x = (T − T_ref)/s_T, g = ΔT/s_ΔT; per-run switch-on offsets are separate
intercepts). Effects with a time constant are linear given it; the constant is
searched on a log grid and refined (profile likelihood).

* ``thermal_lag`` (``tau_s``): the bias sees T_lag, a first-order lag of the
  estimated temperature, y' = (T − y)/τ, y(0) = T(0). T_lag replaces T in every
  temperature term (ΔT stays). To first order T_lag ≈ T − τ·dT/dt, which the
  ΔT terms absorb; what remains is the lag's shape at ramp corners and holds.
* ``hysteresis`` (``amplitude_dps``, ``transition_c``): bias += A·h. The
  direction d of the last move (+1 heating, −1 cooling, 0 before the first) is
  a play operator of width 0.25 °C on T (:func:`direction_state`); after each
  flip, h saturates towards d with the temperature travelled since:
  h = d + (h₀ − d)·exp(−D/w), D = Σ|ΔT| since the flip, w = ``transition_c``
  (0 = an abrupt switch; searched on a grid). Noise in holds only pushes h
  further towards d, so the memory persists through holds. A is half the
  separation of the saturated branches, positive when heating lies above.
* ``warmup`` (``amplitude_dps``, ``tau_s``): bias += A·exp(−t/τ), t = time since
  power-on, independent of temperature.
* ``cubic`` (``coefficient_dps_per_c3``): bias += c·(T − T_ref)³; c is also the
  T³ coefficient of the expanded polynomial, whatever T_ref.
* ``gradient_quadratic`` (``coefficient_dps_per_c2``): bias += c·ΔT².
* ``drift`` (``slope_dps_per_h``): bias += s·t/3600.

:func:`add_bias` is the matching simulator extension: it adds a fitted
extended model's bias to a simulated run, evaluated on the simulator's true
die temperature and gradient.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from gyrotherm._errors import CalibrationError
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling, Term, get_model

FloatArray = NDArray[np.float64]

EFFECTS: tuple[str, ...] = (
    "thermal_lag", "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift",
)
#: Log grids of the nonlinear parameter (time constant, s) of the effects that have one.
TAU_GRIDS: Mapping[str, tuple[float, ...]] = {
    "thermal_lag": tuple(float(v) for v in np.geomspace(10.0, 2000.0, 25)),
    "warmup": tuple(float(v) for v in np.geomspace(20.0, 3600.0, 24)),
    "hysteresis": (0.0, *(float(v) for v in np.geomspace(0.1, 10.0, 13))),
}
#: Name of each effect's searched parameter in the report.
GRID_PARAM = {"thermal_lag": "tau_s", "warmup": "tau_s", "hysteresis": "transition_c"}
BASE_COLUMNS = ("T^2", "T", "dT", "T*dT")
#: Width of the play operator giving the direction of the last move, °C.
DIRECTION_WIDTH_C = 0.25
DESCRIPTIONS: Mapping[str, str] = {
    "thermal_lag": "the bias follows a first-order lag of the sensed temperature",
    "hysteresis": "heating and cooling branches differ at equal T, through holds",
    "warmup": "a power-on transient A·exp(−t/τ), independent of T",
    "cubic": "a third-order temperature dependence",
    "gradient_quadratic": "bias grows with ΔT², same sign heating and cooling",
    "drift": "a slow linear drift with time since power-on",
}


def lowpass(values: FloatArray, tau_s: float, *, step_s: float = 1.0) -> FloatArray:
    """First-order lag with time constant ``tau_s`` on a uniform grid, y(0) = x(0)."""
    if len(values) == 0:
        return values.copy()
    a = float(np.exp(-step_s / tau_s))
    y, _ = lfilter([1.0 - a], [1.0, -a], values, zi=[a * float(values[0])])
    return np.asarray(y, dtype=np.float64)


def direction_state(temperature_c: FloatArray, width_c: float, *, every: int = 1) -> FloatArray:
    """Play operator: +1 after T rose ``width_c`` above its last low, −1 after it fell
    ``width_c`` below its last high, 0 before the first such move.

    ``every`` > 1 runs the operator on every ``every``-th sample and holds the
    state in between (faster; switch times shift by less than ``every`` samples).
    """
    values = temperature_c[::every] if every > 1 else temperature_c
    out = np.zeros(len(values))
    state = 0.0
    lo = hi = float(values[0]) if len(values) else 0.0
    for i, v in enumerate(values.tolist()):
        hi = max(hi, v)
        lo = min(lo, v)
        if state >= 0.0 and hi - v > width_c:
            state, lo = -1.0, v
        elif state <= 0.0 and v - lo > width_c:
            state, hi = 1.0, v
        out[i] = state
    if every > 1:
        out = np.repeat(out, every)[: len(temperature_c)]
    return out


def hysteresis_state(
    temperature_c: FloatArray, direction: FloatArray, width_c: float
) -> FloatArray:
    """h(t): saturation towards the play-operator direction over ``width_c`` of travel."""
    n = len(temperature_c)
    h = np.zeros(n)
    if n == 0:
        return h
    if width_c <= 0.0:
        return np.asarray(direction, dtype=np.float64).copy()
    step = np.abs(np.diff(temperature_c, prepend=temperature_c[0]))
    cuts = np.r_[0, np.flatnonzero(np.diff(direction) != 0) + 1, n]
    prev = 0.0
    for a, b in itertools.pairwise(cuts):
        d = float(direction[a])
        travel = np.cumsum(step[a:b])
        h[a:b] = d + (prev - d) * np.exp(-travel / width_c)
        prev = float(h[b - 1])
    return h


def design(
    time_s: FloatArray,
    temperature_c: FloatArray,
    delta_t_c: FloatArray,
    direction: FloatArray | None,
    scaling: Scaling,
    effects: Mapping[str, float],
    *,
    step_s: float = 1.0,
    direction_width_c: float = DIRECTION_WIDTH_C,
) -> tuple[tuple[str, ...], FloatArray]:
    """Column names and design matrix of the paper model extended by ``effects``.

    ``effects`` maps effect name → its time constant (s), or 0.0 for effects
    without one. No intercept column: offsets are per run. ``direction`` is
    the play-operator state of ``temperature_c`` (computed when None); the
    hysteresis regressor follows the sensed temperature even with
    ``thermal_lag`` (its saturation width absorbs a lag), so that the lag
    cannot act as a timing knob of the hysteresis.
    """
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise CalibrationError(f"unknown effects {sorted(unknown)}; known: {', '.join(EFFECTS)}")
    temp = temperature_c
    if "thermal_lag" in effects:
        temp = lowpass(temperature_c, effects["thermal_lag"], step_s=step_s)
    x, g = scaling.centre(temp, delta_t_c)
    names: list[str] = list(BASE_COLUMNS)
    cols = [x * x, x, g, x * g]
    for name in EFFECTS:
        if name not in effects:
            continue
        if name == "hysteresis":
            if direction is None:
                every = max(1, round(10.0 / step_s))
                direction = direction_state(temperature_c, direction_width_c, every=every)
            cols.append(hysteresis_state(temperature_c, direction, effects[name]))
        elif name == "warmup":
            cols.append(np.exp(-time_s / effects[name]))
        elif name == "cubic":
            cols.append(x**3)
        elif name == "gradient_quadratic":
            cols.append(g * g)
        elif name == "drift":
            cols.append(time_s / 3600.0)
        else:
            continue
        names.append(name)
    return tuple(names), np.column_stack(cols)


def effect_params(
    name: str, coefficient: float, scaling: Scaling, tau_s: float
) -> dict[str, float]:
    """Physical parameters of effect ``name`` from its fitted column coefficient."""
    if name == "thermal_lag":
        return {"tau_s": tau_s}
    if name == "hysteresis":
        return {"amplitude_dps": coefficient, "transition_c": tau_s}
    if name == "warmup":
        return {"amplitude_dps": coefficient, "tau_s": tau_s}
    if name == "cubic":
        return {"coefficient_dps_per_c3": coefficient / scaling.t_scale_c**3}
    if name == "gradient_quadratic":
        return {"coefficient_dps_per_c2": coefficient / scaling.dt_scale_c**2}
    if name == "drift":
        return {"slope_dps_per_h": coefficient}
    raise CalibrationError(f"unknown effect {name!r}")


@dataclass(frozen=True)
class ExtendedModel:
    """A fitted bias model: paper terms + effects, one axis, common intercept."""

    scaling: Scaling
    effects: Mapping[str, float]
    columns: tuple[str, ...]
    coefficients: tuple[float, ...]
    intercept_dps: float
    offsets_dps: Mapping[str, float] = field(default_factory=dict)
    direction_width_c: float = DIRECTION_WIDTH_C

    @property
    def name(self) -> str:
        return "+".join(["paper", *[e for e in EFFECTS if e in self.effects]])

    def coefficient(self, column: str) -> float:
        return self.coefficients[self.columns.index(column)]

    def params(self) -> dict[str, dict[str, float]]:
        """Physical parameters per effect."""
        out = {}
        for name in EFFECTS:
            if name in self.effects:
                c = self.coefficient(name) if name in self.columns else 0.0
                out[name] = effect_params(name, c, self.scaling, self.effects[name])
        return out

    def paper_physical(self) -> dict[str, float]:
        """Paper-term coefficients in physical units (T, ΔT in °C), with the intercept."""
        spec = get_model("paper")
        centred = {Term.parse(n): self.coefficient(n) for n in BASE_COLUMNS}
        vec = np.array([centred.get(t, self.intercept_dps) for t in spec.terms])
        phys = self.scaling.to_physical(spec, vec)
        return {t.name: phys[t] for t in spec.terms}

    def bias(
        self,
        time_s: FloatArray,
        temperature_c: FloatArray,
        delta_t_c: FloatArray,
        *,
        direction: FloatArray | None = None,
        step_s: float | None = None,
    ) -> FloatArray:
        """Bias (°/s) along a uniformly sampled series (offsets: the common intercept)."""
        step = step_s if step_s is not None else (
            float(np.median(np.diff(time_s))) if len(time_s) > 1 else 1.0)
        _, a = design(time_s, temperature_c, delta_t_c, direction, self.scaling,
                      self.effects, step_s=step, direction_width_c=self.direction_width_c)
        return np.asarray(a @ np.asarray(self.coefficients) + self.intercept_dps)


def add_bias(run: Run, model: ExtendedModel, axis: str) -> Run:
    """The simulator extension: ``run`` with ``model``'s bias added to axis ``axis``.

    Evaluated on the simulator's truth columns ``true_temperature_c`` and
    ``true_delta_t_c`` (so effects act on the die, as the physics would).
    """
    if "true_temperature_c" not in run.extra or "true_delta_t_c" not in run.extra:
        raise CalibrationError(
            f"run {run.name!r}: add_bias needs the simulator's true_temperature_c and "
            "true_delta_t_c columns"
        )
    b = model.bias(run.time_s, run.extra["true_temperature_c"], run.extra["true_delta_t_c"])
    rates = dict(run.rates_dps)
    rates[axis] = rates[axis] + b
    truth = dict(run.true_bias_dps)
    truth[axis] = truth.get(axis, np.zeros(len(run))) + b
    from dataclasses import replace

    return replace(run, rates_dps=rates, true_bias_dps=truth)
