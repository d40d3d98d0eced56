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

Whether a structure is there at all is the readout replays' question
(:func:`~._resolve.readout_structure`: it must beat, by the margin, what replays of
the runs' readout without it give a spline in the same variable; the replays
re-read a step-free temperature through the runs' hold and LSB, so they produce
the code-change jumps of the ΔT estimate too). A structure that passes them but
whose ``steepest`` span is narrower than the span above is real, and the readout
cannot place it: where within that span it changes is below what the data show.
It is reported (it is in the data, its correction buys its held-out gain) with a
note saying so (:func:`placement`). A saturating response to the gradient,
A·tanh(ΔT/s) with s = 1–2 °C, read through a 1 °C readout (ΔT span 5.9 °C) is
such a structure.

Until issue 19's round 4 such a structure was a verdict ("not resolvable at this
readout") before the replays were asked; on development seeds 31–36 at the
1 °C / 1.3 s / 3-run readout that discarded two saturating ΔT responses the
replays pass, while the null development seeds' narrow ΔT structures (e.g. dev
seed 102) are verdicts of the replays as well (docs/findings.md §6).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

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


def placement(u: Unexplained, resolution: Resolution) -> str | None:
    """A note when ``u``'s ``steepest`` span is narrower than the readout can place
    (module docstring); else None."""
    need = resolution.spans().get(u.variable)
    lo, hi = u.steepest  # how sharp it is, not how far it reaches (``where``)
    if need is None or not hi - lo < need:
        return None
    return (f"its steepest part, {u.variable} in [{lo:.3g}, {hi:.3g}] (span {hi - lo:.3g}), is "
            f"narrower than the readout can place, {need:.3g} ({resolution.why(u.variable)}): "
            f"the structure is in the data (it beats readout replays without it), but where "
            f"within about {need:.3g} of that span it changes is below what the readout shows")
