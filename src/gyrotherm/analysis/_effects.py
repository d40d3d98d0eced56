"""Candidate physical effects: regressors of the bias model and simulator add-ons.

Every effect extends the paper model's design matrix (terms x², x, g, x·g in
x = (T − T_ref)/s_T, g = ΔT/s_ΔT; per-run switch-on offsets are separate
intercepts). Effects with a time constant are linear given it; the constant is
searched on a log grid and refined (profile likelihood).

* ``thermal_lag`` (``tau_s``): the bias sees T_lag, a first-order lag of the
  estimated temperature, y' = (T − y)/τ, y(0) = T(0). T_lag replaces T in every
  temperature term (ΔT stays). To first order T_lag ≈ T − τ·dT/dt, which the
  ΔT terms absorb; what remains is the lag's shape at ramp corners and holds.
* ``hysteresis`` (``amplitude_dps``, ``transition_c``): bias += A·h, a
  rate-independent memory of the direction of the last move of the
  *structure* temperature T_s (T_lag when the model has ``thermal_lag``: the
  hysteresis is a property of the MEMS structure and follows its temperature;
  else T). One length scale w = ``transition_c`` (°C, searched on a log grid)
  sets both the dead band and the saturation: the direction d (+1 heating, −1
  cooling, 0 before the first move) is a play operator of width w on T_s
  (:func:`direction_state`: it flips once T_s has moved w from its last
  extreme), and after each flip h saturates towards d with the temperature
  travelled since, h = d + (h₀ − d)·exp(−D/w), D = Σ|ΔT_s| since the flip.
  Noise in holds only pushes h further towards d, so the memory persists
  through holds. A is half the separation of the saturated branches, positive
  when heating lies above. (A fixed narrow band with w only shaping the
  saturation cannot delay the switch; a lag then served as the hysteresis'
  timing knob and was reported as a spurious ``thermal_lag``.)
* ``warmup`` (``amplitude_dps``, ``tau_s``): bias += A·exp(−t/τ), t = time since
  power-on, independent of temperature.
* ``cubic`` (``coefficient_dps_per_c3``): bias += c·(T − T_ref)³; c is also the
  T³ coefficient of the expanded polynomial, whatever T_ref.
* ``gradient_quadratic`` (``coefficient_dps_per_c2``): bias += c·ΔT².
* ``drift`` (``slope_dps_per_h``): bias += s·t/3600.

:func:`design` builds the columns for fitting (vectorised, uniform grid).
:meth:`ExtendedModel.bias` evaluates a fitted model with the vehicle's online
kernel (:mod:`gyrotherm.compensation._effects`), sample by sample at the
series' own (irregular) time steps: one implementation of the effects for the
vehicle and the offline evaluation. :func:`add_bias` is the matching simulator
extension (a fitted model's bias added to a simulated run, evaluated on the
simulator's true die temperature and gradient): the kernel too, or on a
uniform grid the vectorised columns that equal it there.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, MutableMapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from gyrotherm._errors import CalibrationError
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling, Term, get_model
from gyrotherm.compensation._correction import Correction
from gyrotherm.compensation._effects import MIN_TRANSITION_C, Effects, EffectsKernel

FloatArray = NDArray[np.float64]

EFFECTS: tuple[str, ...] = (
    "thermal_lag", "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift",
)
TAU_GRIDS: Mapping[str, tuple[float, ...]] = {
    "thermal_lag": tuple(float(v) for v in np.geomspace(10.0, 2000.0, 25)),
    "warmup": tuple(float(v) for v in np.geomspace(20.0, 3600.0, 24)),
    "hysteresis": tuple(float(v) for v in np.geomspace(0.1, 10.0, 13)),
}
"""Log grids of the nonlinear parameter of the effects that have one (s; °C for
``hysteresis``)."""
#: Name of each effect's searched parameter in the report.
GRID_PARAM = {"thermal_lag": "tau_s", "warmup": "tau_s", "hysteresis": "transition_c"}
BASE_COLUMNS = ("T^2", "T", "dT", "T*dT")
#: Width of the play operator giving the direction of the last move for the residual
#: statistics and plots (the hysteresis regressor uses its own width), °C.
DIRECTION_WIDTH_C = 0.25
_PLAY_CHUNK = 512
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

    The low (high) is the minimum (maximum) since the last flip to −1 (+1), or
    since the start while the state is 0; a flip is checked after the sample
    has updated them, and falling wins a tie. Vectorised by chunks: each
    flip costs at most one chunk of running extrema.

    ``every`` > 1 runs the operator on every ``every``-th sample and holds the
    state in between (switch times shift by less than ``every`` samples).
    """
    values = np.asarray(temperature_c[::every] if every > 1 else temperature_c,
                        dtype=np.float64)
    n = len(values)
    out = np.zeros(n)
    if n == 0:
        return out
    state = 0.0
    hi = lo = float(values[0])
    i = 0
    while i < n:
        seg = values[i: i + _PLAY_CHUNK]
        hi_run = np.maximum(np.maximum.accumulate(seg), hi)
        lo_run = np.minimum(np.minimum.accumulate(seg), lo)
        down = hi_run - seg > width_c if state >= 0.0 else np.zeros(len(seg), dtype=bool)
        up = seg - lo_run > width_c if state <= 0.0 else np.zeros(len(seg), dtype=bool)
        hit = np.flatnonzero(down | up)
        if len(hit) == 0:
            out[i: i + len(seg)] = state
            hi, lo = float(hi_run[-1]), float(lo_run[-1])
            i += len(seg)
            continue
        k = int(hit[0])
        out[i: i + k] = state
        if down[k]:
            state, lo, hi = -1.0, float(seg[k]), float(hi_run[k])
        else:
            state, hi, lo = 1.0, float(seg[k]), float(lo_run[k])
        out[i + k] = state
        i += k + 1
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


ColumnCache = MutableMapping[tuple[str, float, float], FloatArray]
"""Columns of one series by (kind, lag τ or 0, parameter), for :func:`design`."""


def design(
    time_s: FloatArray,
    temperature_c: FloatArray,
    delta_t_c: FloatArray,
    scaling: Scaling,
    effects: Mapping[str, float],
    *,
    step_s: float = 1.0,
    cache: ColumnCache | None = None,
    centred: bool = False,
    append: FloatArray | None = None,
    hysteresis_follows_lag: bool = True,
) -> tuple[tuple[str, ...], FloatArray]:
    """Column names and design matrix of the paper model extended by ``effects``.

    ``effects`` maps effect name → its nonlinear parameter (time constant, s;
    ``transition_c`` for hysteresis), or 0.0 for effects without one. No
    intercept column: offsets are per run. With ``thermal_lag``, the lagged
    temperature replaces T in the temperature terms and drives the hysteresis.
    ``cache`` (one per series, with fixed ``scaling`` and ``step_s``) keeps
    columns for reuse across calls with other effect sets. ``centred``: every
    column minus its mean. ``append``: a last column (not named) copied in as is.
    ``hysteresis_follows_lag=False`` drives the hysteresis by T even with a lag
    (to test whether a lag earns its place by more than timing the hysteresis).
    """
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise CalibrationError(f"unknown effects {sorted(unknown)}; known: {', '.join(EFFECTS)}")
    memo: ColumnCache = cache if cache is not None else {}
    lag = round(effects["thermal_lag"], 6) if "thermal_lag" in effects else 0.0
    hyst_lag = lag if hysteresis_follows_lag else 0.0

    def column(kind: str, param: float, make: Callable[[], FloatArray],
               at: float | None = None) -> FloatArray:
        """Cached column; ``at``: the lag it depends on (None: none)."""
        key = (kind, round(at, 6) if at is not None else -1.0, round(param, 6))
        if key not in memo:
            memo[key] = make()
        if not centred or kind == "temp":
            return memo[key]
        ckey = ("c " + kind, *key[1:])
        if ckey not in memo:
            raw = memo[key]
            memo[ckey] = raw - raw.mean(axis=-1, keepdims=True)
        return memo[ckey]

    def lagged(tau: float) -> Callable[[], FloatArray]:
        return lambda: lowpass(temperature_c, tau, step_s=step_s) if tau else temperature_c

    def base() -> FloatArray:  # rows: x², x, g, x·g, x³, g²
        x, g = scaling.centre(column("temp", 0.0, lagged(lag), lag), delta_t_c)
        return np.array([x * x, x, g, x * g, x**3, g * g])

    def hysteresis(width: float) -> Callable[[], FloatArray]:
        def make() -> FloatArray:
            temp = column("temp", 0.0, lagged(hyst_lag), hyst_lag)
            return hysteresis_state(temp, direction_state(temp, width), width)
        return make

    def warmup(tau: float) -> Callable[[], FloatArray]:
        return lambda: np.asarray(np.exp(-time_s / tau), dtype=np.float64)

    def drift() -> FloatArray:
        return np.asarray(time_s / 3600.0, dtype=np.float64)

    block = column("base", 0.0, base, lag)
    names: list[str] = list(BASE_COLUMNS)
    rows: list[FloatArray] = [block[0], block[1], block[2], block[3]]
    for name in EFFECTS:
        if name not in effects:
            continue
        if name == "hysteresis":
            width = max(effects[name], MIN_TRANSITION_C)
            rows.append(column("hysteresis", width, hysteresis(width), hyst_lag))
        elif name == "warmup":
            rows.append(column("warmup", effects[name], warmup(effects[name])))
        elif name == "cubic":
            rows.append(block[4])
        elif name == "gradient_quadratic":
            rows.append(block[5])
        elif name == "drift":
            rows.append(column("drift", 0.0, drift))
        else:
            continue
        names.append(name)
    if append is not None:
        rows.append(append)
    out = np.empty((len(rows), len(time_s)))
    for i, row in enumerate(rows):
        out[i] = row
    return tuple(names), out.T


def effect_params(
    name: str, coefficient: float, scaling: Scaling, tau_s: float
) -> dict[str, float]:
    """Physical parameters of effect ``name`` from its fitted column coefficient."""
    if name == "thermal_lag":  # the value design() uses (it rounds the lag it caches)
        return {"tau_s": round(tau_s, 6)}
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
        phys = self.scaling.to_physical(spec, np.array(self.base_coefficients()))
        return {t.name: phys[t] for t in spec.terms}

    def base_coefficients(self) -> tuple[float, ...]:
        """The paper terms' centred coefficients in ``get_model("paper")`` order
        (T², T, ΔT, T·ΔT, 1), the common intercept last."""
        spec = get_model("paper")
        centred = {Term.parse(n): self.coefficient(n) for n in BASE_COLUMNS}
        return tuple(centred.get(t, self.intercept_dps) for t in spec.terms)

    def online_effects(self, *, t_on_max_s: float | None = None) -> Effects:
        """The effects for :class:`~gyrotherm.compensation._effects.EffectsKernel`
        (``cubic`` about ``scaling.t_ref_c``; ``t_on_max_s`` limits a drift)."""
        params: dict[str, dict[str, float | None]] = {k: dict(v) for k, v in self.params().items()}
        if "drift" in params and t_on_max_s is not None:
            params["drift"]["t_on_max_s"] = t_on_max_s
        return Effects.from_params(params, t_ref_c=self.scaling.t_ref_c)

    def bias(
        self, time_s: FloatArray, temperature_c: FloatArray, delta_t_c: FloatArray,
    ) -> FloatArray:
        """Bias (°/s) along a series (offsets: the common intercept), t = time since
        power-on: the online kernel's structure temperature and effects, the paper
        polynomial at T_s (as the vehicle computes it; no range clamping). Without
        effects the kernel is the identity on (T, ΔT) and is skipped."""
        temp = np.asarray(temperature_c, dtype=np.float64)
        dtemp = np.asarray(delta_t_c, dtype=np.float64)
        extra = np.zeros(len(temp))
        effects = self.online_effects()
        if effects.names:
            out = EffectsKernel(effects).series(np.asarray(time_s, dtype=np.float64), temp,
                                                dtemp)
            temp, dtemp, extra = out.structure_temperature_c, out.delta_t_c, out.bias_dps
        x, g = self.scaling.centre(temp, dtemp)
        base = get_model("paper").design(x, g) @ np.asarray(self.base_coefficients())
        return np.asarray(base + extra, dtype=np.float64)


def correction_bias(correction: Correction, time_s: FloatArray, temperature_c: FloatArray,
                    delta_t_c: FloatArray) -> FloatArray:
    """A deployable ``correction`` (calibration v2, :mod:`gyrotherm.compensation._correction`)
    over a series, °/s: its linear spline at the variable it names (T, ΔT, or the time
    since power-on ``time_s``, negative times as 0 as the kernel takes them), constant
    outside its knots. ``np.interp`` is that spline; equal to the kernel's
    :meth:`Correction.value` to rounding."""
    v = {"temperature_c": temperature_c, "delta_t_c": delta_t_c,
         "time_since_power_on_s": np.maximum(np.asarray(time_s, dtype=np.float64), 0.0)
         }[correction.variable]
    return np.interp(np.asarray(v, dtype=np.float64), correction.knots, correction.values_dps)


def add_bias(run: Run, model: ExtendedModel, axis: str, *,
             correction: Correction | None = None) -> Run:
    """The simulator extension: ``run`` with ``model``'s bias added to axis ``axis``, and
    with the ``correction`` a calibration v2 carries for that axis when given (the
    diagnosis' unexplained structure, deployed: :func:`correction_bias`).

    Evaluated on the simulator's truth columns ``true_temperature_c`` and
    ``true_delta_t_c`` (so effects act on the die, as the physics would), from the
    run's first row: with the online kernel (:meth:`ExtendedModel.bias`), except on a
    uniform time grid (the simulator's), where the diagnosis' vectorised columns equal
    the kernel to 1e-12 (tests/compensation/test_effects_online.py, and
    tests/analysis/test_to_calibration.py on a simulated run) at ~1/50 of its cost: the
    diagnosis replays every run 5× per model, 2.5 M kernel steps on 7 × 2 h at 10 Hz.
    """
    if "true_temperature_c" not in run.extra or "true_delta_t_c" not in run.extra:
        raise CalibrationError(
            f"run {run.name!r}: add_bias needs the simulator's true_temperature_c and "
            "true_delta_t_c columns"
        )
    temp, dtemp = run.extra["true_temperature_c"], run.extra["true_delta_t_c"]
    steps = np.diff(run.time_s)
    step = float(np.median(steps)) if len(steps) else 1.0
    if len(steps) and step > 0 and float(np.ptp(steps)) <= 1e-9 * step:
        _, a = design(run.time_s, temp, dtemp, model.scaling, model.effects, step_s=step)
        b = np.asarray(a @ np.asarray(model.coefficients) + model.intercept_dps)
    else:
        b = model.bias(run.time_s, temp, dtemp)
    if correction is not None:
        b = b + correction_bias(correction, run.time_s, temp, dtemp)
    rates = dict(run.rates_dps)
    rates[axis] = rates[axis] + b
    truth = dict(run.true_bias_dps)
    truth[axis] = truth.get(axis, np.zeros(len(run))) + b
    return replace(run, rates_dps=rates, true_bias_dps=truth)
