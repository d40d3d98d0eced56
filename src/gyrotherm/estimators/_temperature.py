"""Kalman filter for the gyro's internal temperature T and its gradient ΔT.

State ``x = [T, Ṫ]`` (°C, °C/s), constant-velocity model with a continuous
white-noise jerk of spectral density ``q`` (°C²/s³)::

    F(dt) = [[1, dt], [0, 1]]
    Q(dt) = q · [[dt³/3, dt²/2], [dt²/2, dt]]
    H     = [1, 0],   R = σ_noise² + LSB²/12      (°C²)

The gradient follows from first-order thermal coupling between the gyro and
its environment, ``τ·dT/dt = T_env − T``, so ``ΔT = T_env − T = τ·Ṫ`` with
``σ_ΔT = τ·σ_Ṫ`` (see docs/model.md). Measurements whose innovation exceeds
``gate_sigma`` standard deviations are rejected as spikes; after
``max_consecutive_rejections`` rejections in a row the filter re-initialises
on the reading (a real step, not a spike). A reading stamped more than
``stale_after_s`` before the filter's time (the time base stepped back) also
re-initialises it; smaller steps back are fused at the filter's time.
Without measurements the state is only predicted, and flagged stale once
``stale_after_s`` passes.

Robustness (any float time stamp, any float reading): the filter never
predicts across more than :data:`MAX_PREDICT_S` (10⁶ s): a reading stamped
further ahead re-initialises it (``time_resets``), a predict-only target
further ahead leaves the state as it is (the estimate turns stale). So
dt ≤ 10⁶ s and ``Q(dt)`` ≤ q·10¹⁸ stay finite, and no time stamp can raise.
Should a step still leave ``x`` or ``P`` non-finite (readings near the float
range), the filter re-initialises on the reading, or, in a predict-only step,
forgets its state (``non_finite_resets``): an initialised filter's ``x`` and
``P`` are always finite. The daemon's pipeline keeps absurd time stamps away
from the filter altogether (``max_time_jump_s``, docs/model.md).

Engines. The filter is written out for its two states in float arithmetic
(``engine="python"``, the default and the daemon's): the same operations, in
the same order, as filterpy's ``KalmanFilter.predict`` (``x ← F x``,
``P ← F P Fᵀ + Q``) and ``update`` (Joseph form), with the products by the
zeros and ones of ``F``, ``H`` and ``I − K H`` left out::

    predict:  T ← T + dt·Ṫ;  P ← F P Fᵀ + Q
    update:   y = z − T,  s = p00 + R,  k = [p00, p10] / s,  x ← x + k·y
              P ← (I − k H) P (I − k H)ᵀ + R·k kᵀ

It imports neither filterpy nor scipy (filterpy's package ``__init__`` imports
scipy.stats, scipy.linalg and scipy.ndimage: ≈ 1 s and 70 MB of the daemon's
start-up). ``engine="filterpy"`` runs the same estimator on filterpy's
``KalmanFilter`` (imported then): the reference that tests check the default
engine against, to 1e-9 on every field of every estimate
(``tests/estimators/test_engines.py``).

The filter's state is private: callers see frozen :class:`TemperatureEstimate`
values, never the mutable ``x`` / ``P``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import ConfigError

FloatArray = NDArray[np.float64]

#: Longest single prediction step, s (10⁶ s ≈ 11.6 days): a numeric safety bound,
#: far beyond any gap over which a prediction still means something
#: (σ_T = √(q·dt³/3) ≈ 180 °C at the default q and dt = 10⁶ s).
MAX_PREDICT_S = 1e6

Engine = Literal["python", "filterpy"]
#: The estimator's engines: ``python`` (float arithmetic, the default) and ``filterpy``
#: (filterpy's ``KalmanFilter``, the reference).
ENGINES: tuple[Engine, ...] = ("python", "filterpy")


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of the temperature / ΔT estimator; all fields carry their unit.

    Fitting and run-time compensation must use the same settings: they are
    stored in every calibration file.
    """

    tau_s: float = 120.0
    """Thermal time constant gyro ↔ environment, s: ΔT = tau_s · dT/dt."""
    noise_c: float = 0.02
    """Temperature sensor white-noise standard deviation, °C."""
    quantisation_c: float = 0.01
    """Temperature sensor resolution (LSB), °C."""
    process_noise_c2_per_s3: float = 1e-7
    """Spectral density q of the white jerk driving dT/dt, °C²/s³."""
    update_period_s: float = 0.0
    """The sensor's refresh period, s: one reading per slot floor(time_s / period) is
    fed to the filter (0 = every reading), offline from a run file's rows
    (:func:`estimate_series`) and online by :meth:`TemperatureEstimator.update`
    alike. Set it when rows or frames repeat a held reading."""
    gate_sigma: float = 6.0
    """Innovation gate, in standard deviations of the innovation."""
    max_consecutive_rejections: int = 5
    """Re-initialise after this many gated readings in a row."""
    stale_after_s: float = 5.0
    """Flag the estimate stale when no reading has arrived for this long, s."""
    initial_rate_std_c_per_s: float = 0.05
    """Prior standard deviation of dT/dt at initialisation, °C/s."""

    def __post_init__(self) -> None:
        bounds: dict[str, tuple[float, float]] = {
            "tau_s": (1e-3, 1e6),
            "noise_c": (0.0, 10.0),
            "quantisation_c": (0.0, 10.0),
            "process_noise_c2_per_s3": (1e-15, 1e3),
            "update_period_s": (0.0, 3600.0),
            "gate_sigma": (1.0, 1e3),
            "max_consecutive_rejections": (1, 1e6),
            "stale_after_s": (1e-3, 1e6),
            "initial_rate_std_c_per_s": (1e-6, 1e3),
        }
        for name, (lo, hi) in bounds.items():
            value = getattr(self, name)
            if not isinstance(value, int | float) or isinstance(value, bool):
                raise ConfigError(f"estimator.{name}: expected a number, got {value!r}")
            if not (lo <= value <= hi) or not math.isfinite(value):
                raise ConfigError(f"estimator.{name} = {value!r} is outside [{lo:g}, {hi:g}]")
        if self.noise_c == 0.0 and self.quantisation_c == 0.0:
            raise ConfigError("estimator: noise_c and quantisation_c cannot both be 0")

    @property
    def measurement_variance_c2(self) -> float:
        """R = σ² + LSB²/12, °C²."""
        return self.noise_c**2 + self.quantisation_c**2 / 12.0

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, where: str = "estimator") -> EstimatorConfig:
        """Build from a mapping; unknown or wrongly typed fields are a ConfigError."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ConfigError(f"{where}: unknown field(s) {sorted(unknown)}; "
                              f"known: {sorted(known)}")
        try:
            return cls(**data)
        except (TypeError, ConfigError) as exc:
            raise ConfigError(f"{where}: {exc}") from exc


@dataclass(frozen=True)
class TemperatureEstimate:
    """Filtered temperature state at ``time_s``.

    ``delta_t_c`` is the gradient ΔT = T_env − T = τ·dT/dt (°C), positive while
    heating. ``stale`` is set when no reading arrived for ``stale_after_s``;
    ``rejected`` when the latest reading was gated out as a spike.
    """

    time_s: float
    temperature_c: float
    rate_c_per_s: float
    delta_t_c: float
    temperature_std_c: float
    rate_std_c_per_s: float
    delta_t_std_c: float
    stale: bool
    rejected: bool
    updates: int
    """Readings fused since the last (re-)initialisation."""


class TemperatureEstimator:
    """Online T / ΔT estimator: a two-state Kalman filter behind a typed API.

    ``engine`` (keyword): ``"python"`` (default) runs the filter in float arithmetic;
    ``"filterpy"`` runs it on filterpy's ``KalmanFilter`` (the reference; imports
    filterpy and scipy). Both give the same estimates (to 1e-9; module docstring).
    """

    def __init__(self, config: EstimatorConfig | None = None, *,
                 engine: Engine = "python") -> None:
        self._cfg = config or EstimatorConfig()
        if engine not in ENGINES:
            raise ConfigError(f"estimator engine {engine!r}: expected one of {list(ENGINES)}")
        self._engine: Engine = engine
        self._r_c2 = self._cfg.measurement_variance_c2
        # the state x = [x0, x1] (°C, °C/s) and P = [[p00, p01], [p10, p11]]; with the
        # filterpy engine, copies of its x and P after every step (float() of each entry)
        self._x0 = self._x1 = 0.0
        self._p00 = self._p01 = self._p10 = self._p11 = 0.0
        # F and Q of the cached dt (s): Q = [[q00, q01], [q01, q11]]
        self._dt = math.nan
        self._q00 = self._q01 = self._q11 = math.nan
        self._kf: Any = None
        if engine == "filterpy":
            from filterpy.kalman import KalmanFilter  # the reference: scipy comes with it

            self._kf = KalmanFilter(dim_x=2, dim_z=1)
            self._kf.H = np.array([[1.0, 0.0]])
            self._kf.R = np.array([[self._r_c2]])
            self._z = np.zeros((1, 1))
            self._f = np.eye(2)
            self._q = np.zeros((2, 2))
        self._time_s: float | None = None
        self._last_reading_s: float | None = None
        self._slot = math.nan  # floor(t / update_period_s) of the latest reading offered
        self._updates = 0
        self._rejections = 0
        self._rejected = False
        self.rejected_total = 0
        """Readings gated out as spikes since construction."""
        self.reinitialisations = 0
        """Re-initialisations after repeated rejections."""
        self.time_resets = 0
        """Re-initialisations because a reading's time was more than ``stale_after_s``
        before the filter's time (the time base stepped back) or more than
        :data:`MAX_PREDICT_S` after it."""
        self.non_finite_resets = 0
        """Re-initialisations (or, predict-only, forgotten states) because a step left
        ``x`` or ``P`` non-finite."""

    @property
    def config(self) -> EstimatorConfig:
        return self._cfg

    @property
    def engine(self) -> Engine:
        """``"python"`` or ``"filterpy"`` (see the class docstring)."""
        return self._engine

    @property
    def initialised(self) -> bool:
        return self._time_s is not None

    def _init(self, time_s: float, temperature_c: float) -> None:
        p00, p11 = self._r_c2, self._cfg.initial_rate_std_c_per_s**2
        self._x0, self._x1 = temperature_c, 0.0
        self._p00, self._p01, self._p10, self._p11 = p00, 0.0, 0.0, p11
        if self._kf is not None:
            self._kf.x = np.array([[temperature_c], [0.0]])
            self._kf.P = np.diag([p00, p11])
            self._mirror()
        self._time_s = time_s
        self._last_reading_s = time_s
        self._rejections = 0
        self._rejected = False
        self._updates = 1

    def _mirror(self) -> None:
        """filterpy engine: copy its x and P into the float state."""
        x, p = self._kf.x, self._kf.P
        self._x0, self._x1 = float(x[0, 0]), float(x[1, 0])
        self._p00, self._p01 = float(p[0, 0]), float(p[0, 1])
        self._p10, self._p11 = float(p[1, 0]), float(p[1, 1])

    def reset(self) -> None:
        """Forget the state: the next reading initialises the filter (counters kept)."""
        self._time_s = None
        self._last_reading_s = None
        self._slot = math.nan
        self._updates = 0
        self._rejections = 0
        self._rejected = False

    def _finite(self) -> bool:
        return math.isfinite(self._x0 + self._x1) and math.isfinite(
            self._p00 + self._p01 + self._p10 + self._p11)

    def _predict_to(self, time_s: float) -> None:
        """Predict to ``time_s``; the caller guarantees 0 < dt ≤ MAX_PREDICT_S or
        dt ≤ 0 (a no-op)."""
        assert self._time_s is not None
        dt = time_s - self._time_s
        if not dt > 0.0:
            return
        # F and Q depend on dt only: rebuild when it changes by more than 1 ppb.
        # Sampled time stamps (i * 0.1 s) differ in the last bits from step to
        # step; reusing F for a dt off by < 1e-9 relative moves the predicted
        # temperature by < 1e-9 * dt * dT/dt (≈ 1e-11 °C at 0.1 °C/s, 0.1 s).
        if not abs(dt - self._dt) <= 1e-9 * dt:  # (True while _dt is NaN)
            q = self._cfg.process_noise_c2_per_s3
            self._q00, self._q01, self._q11 = q * (dt**3 / 3.0), q * (dt**2 / 2.0), q * dt
            self._dt = dt
            if self._kf is not None:
                self._f = np.array([[1.0, dt], [0.0, 1.0]])
                self._q = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        if self._kf is not None:
            self._kf.predict(F=self._f, Q=self._q)
            self._mirror()
        else:  # x ← F x;  P ← F P Fᵀ + Q, with A = F P
            c = self._dt
            p10, p11 = self._p10, self._p11
            self._x0 = self._x0 + c * self._x1
            a00, a01 = self._p00 + c * p10, self._p01 + c * p11
            self._p00 = a00 + a01 * c + self._q00
            self._p01 = a01 + self._q01
            self._p10 = p10 + p11 * c + self._q01
            self._p11 = p11 + self._q11
        self._time_s = time_s

    def _kalman_update(self, temperature_c: float) -> None:
        """Fuse the reading (°C) into the predicted state: filterpy's ``update``."""
        if self._kf is not None:
            self._z[0, 0] = temperature_c
            self._kf.update(self._z)
            self._mirror()
            return
        r = self._r_c2
        p00, p01, p10, p11 = self._p00, self._p01, self._p10, self._p11
        y = temperature_c - self._x0
        si = 1.0 / (p00 + r)
        k0, k1 = p00 * si, p10 * si
        self._x0 = self._x0 + k0 * y
        self._x1 = self._x1 + k1 * y
        i00 = 1.0 - k0  # I − k H = [[i00, 0], [−k1, 1]];  A = (I − k H) P
        a00, a01 = i00 * p00, i00 * p01
        a10, a11 = p10 - k1 * p00, p11 - k1 * p01
        self._p00 = a00 * i00 + k0 * r * k0
        self._p01 = a01 - a00 * k1 + k0 * r * k1
        self._p10 = a10 * i00 + k1 * r * k0
        self._p11 = a11 - a10 * k1 + k1 * r * k1

    def update(self, time_s: float, temperature_c: float) -> TemperatureEstimate:
        """Predict to ``time_s`` (s) and fuse the reading ``temperature_c`` (°C).

        Readings older than the filter's time are fused at the filter's time
        (no retrodiction). Non-finite readings are rejected.

        With ``update_period_s`` P > 0 only a reading that opens a new slot
        floor(t / P) is fused (the rule of :func:`estimate_series`, so online and
        offline features agree): a later one in the same slot repeats the sensor's
        held reading. It is not fused, but it counts as arrived for the stale flag
        (unless the slot's reading was rejected), also when P > ``stale_after_s``.
        """
        period = self._cfg.update_period_s
        if period > 0 and math.isfinite(time_s):
            slot = math.floor(time_s / period + 1e-9)
            if slot == self._slot:
                if not self._rejected and self._last_reading_s is not None:
                    self._last_reading_s = max(time_s, self._last_reading_s)
                return self.estimate(time_s)
            self._slot = slot
        self._fuse(time_s, temperature_c)
        if not math.isfinite(time_s):
            time_s = self._time_s or 0.0
        return self.estimate(time_s)

    def _fuse(self, time_s: float, temperature_c: float) -> None:
        if not math.isfinite(temperature_c) or not math.isfinite(time_s):
            self._rejected = True
            self.rejected_total += 1
            return
        if self._time_s is None:
            self._init(time_s, temperature_c)
            return
        if (time_s < self._time_s - self._cfg.stale_after_s
                or time_s > self._time_s + MAX_PREDICT_S):
            # the time base stepped back (clock step, restarted log) or jumped
            # beyond any meaningful prediction: start again
            self.time_resets += 1
            self._init(time_s, temperature_c)
            return
        self._predict_to(time_s)
        if not self._finite():  # readings near the float range
            self.non_finite_resets += 1
            self._init(time_s, temperature_c)
            return
        innovation = temperature_c - self._x0
        s = self._p00 + self._r_c2
        if innovation * innovation > self._cfg.gate_sigma**2 * s:
            self._rejections += 1
            self.rejected_total += 1
            self._rejected = True
            if self._rejections >= self._cfg.max_consecutive_rejections:
                self.reinitialisations += 1
                self._init(max(time_s, self._time_s), temperature_c)
            return
        self._kalman_update(temperature_c)
        if not self._finite():
            self.non_finite_resets += 1
            self._init(max(time_s, self._time_s), temperature_c)
            return
        self._rejections = 0
        self._rejected = False
        self._updates += 1
        self._last_reading_s = max(time_s, self._last_reading_s or time_s)

    def _state(self) -> tuple[float, float]:
        return self._x0, self._x1

    def _covariance(self) -> tuple[float, float, float, float]:
        return self._p00, self._p01, self._p10, self._p11

    def predict(self, time_s: float) -> TemperatureEstimate:
        """Advance to ``time_s`` without a reading (predict-only). A non-finite
        ``time_s``, or one more than :data:`MAX_PREDICT_S` after the filter's
        time, leaves the state unchanged (the estimate is stale by then); one
        before the filter's time is a no-op. Never raises."""
        t0 = self._time_s
        if t0 is not None and t0 < time_s <= t0 + MAX_PREDICT_S:
            self._predict_to(time_s)
            if not self._finite():
                self.non_finite_resets += 1
                self.reset()
        return self.estimate(time_s)

    def estimate(self, time_s: float | None = None) -> TemperatureEstimate:
        """The current estimate; ``time_s`` (s) decides the stale flag only: stale when
        ``max(time_s, filter time) − last reading > stale_after_s``, and always for a
        non-finite ``time_s`` (the estimate's ``time_s`` is then the filter's)."""
        if self._time_s is None:
            nan = math.nan
            t = nan if time_s is None else time_s
            return TemperatureEstimate(t, nan, nan, nan, nan, nan, nan, True, self._rejected, 0)
        forced_stale = time_s is not None and not math.isfinite(time_s)
        now = self._time_s if time_s is None or forced_stale else max(time_s, self._time_s)
        tau = self._cfg.tau_s
        x1 = self._x1
        rate_std = math.sqrt(max(self._p11, 0.0))
        assert self._last_reading_s is not None
        return TemperatureEstimate(
            time_s=now,
            temperature_c=self._x0,
            rate_c_per_s=x1,
            delta_t_c=tau * x1,
            temperature_std_c=math.sqrt(max(self._p00, 0.0)),
            rate_std_c_per_s=rate_std,
            delta_t_std_c=tau * rate_std,
            stale=forced_stale or (now - self._last_reading_s) > self._cfg.stale_after_s,
            rejected=self._rejected,
            updates=self._updates,
        )
