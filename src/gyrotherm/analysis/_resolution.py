"""How finely the readout lets the diagnosis place an unexplained structure.

An unexplained structure (:mod:`._unexplained`) is a linear spline in one
variable v, reported with ``steepest``: the span of v over which it changes
fastest (``where``, the whole span it reaches over, is wider). The readout
sets the smallest span of v the data can show:

* **T** (``temperature_c``): one readout LSB q. Between code changes the
  reading says nothing about where T is within the code.
* **ΔT** (``delta_t_c`` = τ·dT/dt): dT/dt is the slope of a
  :data:`~._prep.DERIVATIVE_WINDOW_S`-s least-squares fit to the 1-s block
  means of the reading (``features="smooth"``). One code step q inside that
  window moves the slope by up to q·Σ_{k>0} k / Σ_k k² (h = half the window:
  3/(2(2h+1)) ≈ 0.0246 /s for 61 s), so the ΔT estimate jumps by
  ΔT_q = τ·q·3/(2(2h+1)) at every code change (τ = 240 s, q = 1 °C: 5.9 °C;
  q = 0.125 °C: 0.74 °C) — a readout artefact, not a gradient.
* **time since power-on**: the hold period (a reading is held that long).

A structure whose ``steepest`` span is narrower than this is not resolvable at
this readout: the variable's own estimate moves by more than the span with a
single code change, so where the structure lies (and whether it is one) is
below what the data show. Such a structure is reported as a
:class:`~._resolve.NotResolvable` verdict (effect ``unexplained:<variable>``)
and the unexplained search is rerun without that variable.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from gyrotherm.analysis._resolve import NotResolvable
from gyrotherm.analysis._unexplained import Unexplained

DERIVATIVE_WINDOW_S = 61
"""Window (s, odd) of the Savitzky–Golay derivative that gives dT/dt (:func:`~._prep._smooth`)."""


def step_slope_per_s(window_s: int = DERIVATIVE_WINDOW_S) -> float:
    """The largest change of a least-squares slope over ``window_s`` 1-s blocks when
    the data step by 1: Σ_{k=1..h} k / Σ_{k=-h..h} k² = 3 / (2(2h + 1))."""
    h = (window_s - 1) // 2
    return 3.0 / (2.0 * (2.0 * h + 1.0))


@dataclass(frozen=True)
class Resolution:
    """The smallest span of each variable the readout can show."""

    lsb_c: float
    tau_s: float
    hold_s: float

    def spans(self) -> Mapping[str, float]:
        return {"temperature_c": self.lsb_c,
                "delta_t_c": self.tau_s * self.lsb_c * step_slope_per_s(),
                "time_since_power_on_s": self.hold_s}

    def why(self, variable: str) -> str:
        if variable == "temperature_c":
            return f"one readout LSB, {self.lsb_c:g} °C"
        if variable == "delta_t_c":
            k = step_slope_per_s()
            return (f"the jump of the ΔT estimate at one code change, τ·LSB·{k:.4f} /s = "
                    f"{self.tau_s:.0f} s × {self.lsb_c:g} °C × {k:.4f} /s "
                    f"({DERIVATIVE_WINDOW_S}-s derivative window)")
        return f"the readout hold period, {self.hold_s:.2f} s"


def unresolved(u: Unexplained, resolution: Resolution) -> NotResolvable | None:
    """The verdict for ``u`` when its ``steepest`` span is narrower than the readout shows."""
    need = resolution.spans().get(u.variable)
    lo, hi = u.steepest  # how sharp it is, not how far it reaches (``where``)
    if need is None or hi - lo >= need:
        return None
    reason = (f"a structure in {u.variable} over [{lo:.3g}, {hi:.3g}] (span {hi - lo:.3g}, "
              f"held-out gain ×{u.gain:.3f}) is narrower than {need:.3g}, "
              f"{resolution.why(u.variable)}: the variable's estimate moves by more than the "
              "span with a single readout code, so the data cannot place it")
    return NotResolvable(f"unexplained:{u.variable}",
                         {"where_low": lo, "where_high": hi, "gain": u.gain,
                          "resolution": need}, reason)
