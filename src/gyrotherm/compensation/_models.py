"""Bias models: sets of monomial terms in temperature T and gradient ΔT.

A model is linear in its coefficients, one coefficient vector per axis::

    bias(T, ΔT) = Σ_j c_j · x^p_j · g^q_j,   x = (T − T_ref)/s_T,  g = ΔT/s_ΔT

with T the gyro's internal temperature (°C), ΔT = T_env − T (°C, estimated as
τ·dT/dt, see :mod:`gyrotherm.estimators`), and bias in °/s. Fitting and
evaluation work in the centred, scaled variables ``x`` and ``g``: in raw
units the columns T² and T are nearly collinear (Tang et al.'s Table 1
coefficients correlate at ≈ −0.999 because T is not centred). Because every
model here is closed under T → T − T_ref (all lower powers of T are present
for each power of ΔT), the centred coefficients map exactly onto physical
ones by binomial expansion, :meth:`Scaling.to_physical`.

Models (name → terms):

* ``paper``: T², T, ΔT, T·ΔT, 1 — Tang et al. 2013, eq. (11);
* ``t2``: T², T, 1 — the temperature-only models of eq. (13);
* ``t3``: T³, T², T, 1 — the cubic in T that PX4 and ArduPilot ship.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, order=True)
class Term:
    """The monomial T^t_power · ΔT^dt_power."""

    t_power: int
    dt_power: int

    @property
    def name(self) -> str:
        parts = []
        if self.t_power:
            parts.append("T" if self.t_power == 1 else f"T^{self.t_power}")
        if self.dt_power:
            parts.append("dT" if self.dt_power == 1 else f"dT^{self.dt_power}")
        return "*".join(parts) or "1"

    @classmethod
    def parse(cls, name: str) -> Term:
        """Inverse of :attr:`name` (``"T^2"``, ``"T*dT"``, ``"1"`` …)."""
        t = d = 0
        if name.strip() != "1":
            for part in name.split("*"):
                base, _, power = part.strip().partition("^")
                try:
                    p = int(power) if power else 1
                except ValueError:
                    raise CalibrationError(f"term {name!r}: bad power {power!r}") from None
                if base == "T" and t == 0 and p > 0:
                    t = p
                elif base == "dT" and d == 0 and p > 0:
                    d = p
                else:
                    raise CalibrationError(f"term {name!r}: unknown factor {part!r}")
        return cls(t, d)


@dataclass(frozen=True)
class ModelSpec:
    """A named set of terms."""

    name: str
    terms: tuple[Term, ...]

    @property
    def term_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)

    @property
    def uses_delta_t(self) -> bool:
        return any(t.dt_power for t in self.terms)

    def design(self, x: FloatArray, g: FloatArray) -> FloatArray:
        """Design matrix (n × k) of the terms in centred variables x, g."""
        cols = [np.ones_like(x) if (t.t_power, t.dt_power) == (0, 0) else
                x**t.t_power * g**t.dt_power for t in self.terms]
        return np.column_stack(cols)


def _spec(name: str, *terms: tuple[int, int]) -> ModelSpec:
    return ModelSpec(name, tuple(Term(*t) for t in terms))


MODELS: dict[str, ModelSpec] = {
    "paper": _spec("paper", (2, 0), (1, 0), (0, 1), (1, 1), (0, 0)),
    "t2": _spec("t2", (2, 0), (1, 0), (0, 0)),
    "t3": _spec("t3", (3, 0), (2, 0), (1, 0), (0, 0)),
}


def get_model(name: str) -> ModelSpec:
    """The model called ``name``; CalibrationError listing the known ones otherwise."""
    try:
        return MODELS[name]
    except KeyError:
        raise CalibrationError(
            f"unknown model {name!r}; known models: {', '.join(MODELS)}"
        ) from None


@dataclass(frozen=True)
class Scaling:
    """Centring and scaling: x = (T − t_ref_c)/t_scale_c, g = ΔT/dt_scale_c."""

    t_ref_c: float
    t_scale_c: float
    dt_scale_c: float

    def __post_init__(self) -> None:
        for name in ("t_scale_c", "dt_scale_c"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise CalibrationError(f"scaling.{name} must be a positive number, got {v!r}")
        if not np.isfinite(self.t_ref_c):
            raise CalibrationError(f"scaling.t_ref_c must be finite, got {self.t_ref_c!r}")

    @classmethod
    def from_data(cls, temperature_c: FloatArray, delta_t_c: FloatArray) -> Scaling:
        """Centre on the middle of the T range, scale by half the range (≥ 1 °C)."""
        lo, hi = float(np.min(temperature_c)), float(np.max(temperature_c))
        dt = float(np.max(np.abs(delta_t_c))) if len(delta_t_c) else 1.0
        return cls(round((lo + hi) / 2, 3), max(round((hi - lo) / 2, 3), 1.0), max(dt, 1.0))

    def centre(self, temperature_c: FloatArray, delta_t_c: FloatArray) -> tuple[
        FloatArray, FloatArray
    ]:
        return (temperature_c - self.t_ref_c) / self.t_scale_c, delta_t_c / self.dt_scale_c

    def to_physical(self, spec: ModelSpec, coefficients: FloatArray) -> dict[Term, float]:
        """Coefficients of T^k·ΔT^q in physical units (T, ΔT in °C, bias in °/s).

        Expands c·((T−T_ref)/s)^p·(ΔT/s_g)^q = c/(s^p s_g^q) Σ_k C(p,k) T^k (−T_ref)^(p−k) ΔT^q.
        """
        terms = set(spec.terms)
        out: dict[Term, float] = {t: 0.0 for t in spec.terms}
        for term, c in zip(spec.terms, coefficients, strict=True):
            p, q = term.t_power, term.dt_power
            factor = float(c) / (self.t_scale_c**p * self.dt_scale_c**q)
            for k in range(p + 1):
                target = Term(k, q)
                if target not in terms:
                    raise CalibrationError(
                        f"model {spec.name!r} lacks term {target.name!r}: "
                        "cannot express it in physical units"
                    )
                out[target] += factor * comb(p, k) * (-self.t_ref_c) ** (p - k)
        return out

    def from_physical(self, spec: ModelSpec, physical: dict[Term, float]) -> FloatArray:
        """Inverse of :meth:`to_physical` (solved exactly as a small linear system)."""
        k = len(spec.terms)
        basis = np.empty((k, k))
        for j in range(k):
            unit = np.zeros(k)
            unit[j] = 1.0
            phys = self.to_physical(spec, unit)
            basis[:, j] = [phys[t] for t in spec.terms]
        target = np.array([physical.get(t, 0.0) for t in spec.terms])
        return np.asarray(np.linalg.solve(basis, target), dtype=np.float64)
