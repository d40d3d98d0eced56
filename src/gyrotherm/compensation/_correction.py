"""A nonparametric correction: the diagnosis' ``unexplained`` structure, deployable.

When the diagnosis finds residual structure no catalogued effect explains (a bias
that is periodic in T, a smooth step, a saturating response to ΔT, ...), it reports a
linear spline in one variable v (docs/model.md §6, ``analysis/_unexplained.py``).
``gyrotherm diagnose --calibration`` writes it into the calibration as the ``correction``
effect of its axis, and the online kernel (:class:`~._effects.EffectsKernel`) adds

    c(v) = linear interpolation of ``values_dps`` at ``knots`` (v clamped to
           [knots[0], knots[-1]]: constant beyond the declared range)

to the bias, with v the estimator's T (``temperature_c``, °C), ΔT (``delta_t_c``, °C)
or the time since power-on t_on (``time_since_power_on_s``, s). Stateless;
O(log K) per sample (a bisection over at most :data:`MAX_KNOTS` knots).

Contract: ``knots`` strictly increasing and finite (2 … :data:`MAX_KNOTS`), one finite
value per knot; the plausibility check bounds it by max |values_dps|.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import Any

from gyrotherm._errors import CalibrationError

VARIABLES = ("temperature_c", "delta_t_c", "time_since_power_on_s")
"""What a correction may be a function of (the diagnosis' variables)."""
MAX_KNOTS = 64


@dataclass(frozen=True)
class Correction:
    """bias += linear spline of ``values_dps`` at ``knots`` in ``variable``, constant
    outside [knots[0], knots[-1]]; ``source``: where it comes from (provenance)."""

    variable: str
    knots: tuple[float, ...]
    values_dps: tuple[float, ...]
    source: str = ""

    def __post_init__(self) -> None:
        if self.variable not in VARIABLES:
            raise CalibrationError(f"Correction.variable: {self.variable!r} is not one of "
                                   f"{', '.join(VARIABLES)}")
        knots = _floats(self.knots, "knots")
        values = _floats(self.values_dps, "values_dps")
        if not 2 <= len(knots) <= MAX_KNOTS:
            raise CalibrationError(f"Correction.knots: {len(knots)} knots, expected 2 … "
                                   f"{MAX_KNOTS}")
        if len(values) != len(knots):
            raise CalibrationError(f"Correction.values_dps: {len(values)} values for "
                                   f"{len(knots)} knots")
        for i in range(1, len(knots)):
            if not knots[i] > knots[i - 1]:
                raise CalibrationError(f"Correction.knots: not strictly increasing at index "
                                       f"{i} ({knots[i - 1]!r}, {knots[i]!r})")
        object.__setattr__(self, "knots", knots)
        object.__setattr__(self, "values_dps", values)
        if not isinstance(self.source, str):
            raise CalibrationError(f"Correction.source: expected text, got {self.source!r}")

    @property
    def range(self) -> tuple[float, float]:
        """The declared range of the variable: [first knot, last knot]."""
        return self.knots[0], self.knots[-1]

    @property
    def max_abs_dps(self) -> float:
        """Largest |c(v)| anywhere (a linear spline's extremes are at its knots)."""
        return max(abs(v) for v in self.values_dps)

    def value(self, v: float) -> float:
        """c(v), °/s (v clamped to :attr:`range`)."""
        k, y = self.knots, self.values_dps
        if v <= k[0]:
            return y[0]
        if v >= k[-1]:
            return y[-1]
        i = bisect_right(k, v) - 1
        w = (v - k[i]) / (k[i + 1] - k[i])
        return y[i] + w * (y[i + 1] - y[i])

    def to_dict(self) -> dict[str, Any]:
        return {"variable": self.variable, "knots": list(self.knots),
                "values_dps": list(self.values_dps), "source": self.source}


def _floats(values: Any, name: str) -> tuple[float, ...]:
    if isinstance(values, str | bytes) or not hasattr(values, "__iter__"):
        raise CalibrationError(f"Correction.{name}: expected a list of numbers, got "
                               f"{values!r:.60}")
    out = []
    for i, v in enumerate(values):
        try:
            f = float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan
        except OverflowError:
            f = math.inf
        if not math.isfinite(f):
            raise CalibrationError(f"Correction.{name}[{i}]: expected a finite number, "
                                   f"got {v!r:.40}")
        out.append(f)
    return tuple(out)


__all__ = ["MAX_KNOTS", "VARIABLES", "Correction"]
