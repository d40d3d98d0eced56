"""Is a structure in time beside a hysteresis the hysteresis' own timing?

The catalogue's hysteresis (:mod:`._effects`) saturates with the temperature travelled
since the last flip, over one width w whatever the rate. A hysteresis whose transition
takes *time* (a relaxation; a width that grows with the ramp rate) is fitted by it with
a misfit at every ramp corner, and because the chamber schedule repeats from run to run,
that misfit is a function of time since power-on: the unexplained search (:mod:`._unexplained`)
then reports a structure in time beside the hysteresis (round 14 of issue 19: 4 of 20
rate-dependent hysteresis devices on the development seeds at 200 Hz, ×1.12–1.15, and
beside the generator's own hysteresis, whose direction relaxes with a 30–120 s lag).

The check: the catalogue's form with a rate-dependent width, w·(1 + |dT/dt|/r₀) —
the travel that saturates h is divided by (1 + |dT/dt|/r₀), i.e. the catalogued
hysteresis of the *rate-warped* temperature T_w = ∫ dT / (1 + |dT/dt|/r₀); r₀ → ∞ is the
catalogue's form, a small r₀ a transition over a time ≈ w/r₀ — on a grid of
(w, r₀) (:data:`WIDTHS_C`, :data:`RATES_C_PER_S`), in the hysteresis' place, without the
structure in time. When it enters in its place like an effect would (the selection's
entry criteria, :func:`~._select.enters`, against the catalogued form without the
structure; its two grid parameters counted in ΔBIC_eff) and the catalogued form *with*
the structure does not beat it by ×(1 + margin) held out, the structure is this misfit:
it is not reported as unexplained, and the hysteresis finding carries a note that its
shape differs (the vehicle's kernel keeps the catalogue's form; the note says what the
calibration does not model).

Only structures in time are tried: a function of T or ΔT is what the other catalogued
effects and the search name, and a timing misfit at the ramps repeats in time.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._effects import direction_state, hysteresis_state, lowpass
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._unexplained import evaluate_with

FloatArray = NDArray[np.float64]

VARIABLE = "time_since_power_on_s"
"""The variable of the structures the check tries."""
WIDTHS_C = tuple(float(v) for v in np.geomspace(0.1, 10.0, 13))
"""Widths w tried, °C (the catalogued hysteresis' grid)."""
RATES_C_PER_S = tuple(float(v) for v in np.geomspace(3e-4, 0.3, 13))
"""Rates r₀ tried, °C/s: the width doubles at |dT/dt| = r₀ (chamber ramps are
0.01–0.06 °C/s)."""


def warped_temperature(time_s: FloatArray, temperature_c: FloatArray,
                       rate_c_per_s: float) -> FloatArray:
    """T_w = T(0) + Σ ΔT / (1 + |dT/dt|/r₀), dT/dt by central differences, °C."""
    t = np.asarray(temperature_c, dtype=np.float64)
    if len(t) < 2:
        return t.copy()
    rate = np.abs(np.gradient(t, np.asarray(time_s, dtype=np.float64)))
    step = np.diff(t, prepend=t[0]) / (1.0 + rate / rate_c_per_s)
    return np.asarray(t[0] + np.cumsum(step), dtype=np.float64)


def rate_width_state(time_s: FloatArray, temperature_c: FloatArray, width_c: float,
                     rate_c_per_s: float) -> FloatArray:
    """h of the catalogued hysteresis (width ``width_c``) on the rate-warped temperature."""
    tw = warped_temperature(time_s, temperature_c, rate_c_per_s)
    return hysteresis_state(tw, direction_state(tw, width_c), width_c)


@dataclass(frozen=True)
class RateWidth:
    """The rate-dependent width that stands in for a structure in time."""

    width_c: float
    rate_c_per_s: float
    heldout_rms_dps: float
    """Held-out RMS with it in the hysteresis' place, without the structure, °/s."""
    catalogued_rms_dps: float
    """… with the catalogued form and without the structure, °/s."""
    with_structure_rms_dps: float
    """… with the catalogued form and the structure, °/s."""

    def note(self) -> str:
        return (f"the shape differs: its transition widens with the rate of temperature "
                f"change — A·h with a width w·(1 + |dT/dt|/r₀), w = {self.width_c:.3g} °C, "
                f"r₀ = {self.rate_c_per_s:.3g} °C/s (a transition over ≈ "
                f"{self.width_c / self.rate_c_per_s:.0f} s at ramps), in its place: held-out "
                f"RMS {self.catalogued_rms_dps:.5f} → {self.heldout_rms_dps:.5f} °/s, where "
                f"the catalogue's form with a structure in time since power-on beside it "
                f"gives {self.with_structure_rms_dps:.5f}; that structure is this misfit, not "
                f"reported as unexplained (the calibration keeps the catalogue's form)")


def _driving(p: Prepared, effects: Mapping[str, float], coupled: bool) -> FloatArray:
    """The temperature the hysteresis follows (the lagged one with ``thermal_lag``)."""
    if coupled and "thermal_lag" in effects:
        return lowpass(p.temperature_c, effects["thermal_lag"])
    return p.temperature_c


def _column(states: Sequence[FloatArray], index: Mapping[int, int]
            ) -> Callable[[Prepared], FloatArray]:
    def column(p: Prepared) -> FloatArray:
        return states[index[id(p)]]
    return column


def rate_width(
    selector: Selector, effects: Mapping[str, float],
    splines: Sequence[tuple[str, FloatArray]], *, margin: float,
) -> RateWidth | None:
    """The rate-dependent width that stands in for the structure in time in ``splines``
    beside ``effects``' hysteresis (module docstring), or None."""
    from gyrotherm.analysis._select import enters

    if "hysteresis" not in effects or VARIABLE not in dict(splines):
        return None
    others = [(v, k) for v, k in splines if v != VARIABLE]
    rest = {k: v for k, v in effects.items() if k != "hysteresis"}
    with_structure = evaluate_with(selector, effects, splines)
    without = evaluate_with(selector, effects, others)
    drive = [_driving(p, effects, selector.coupled) for p in selector.runs]
    index = {id(p): i for i, p in enumerate(selector.runs)}
    best: tuple[Evaluation, float, float] | None = None
    for r0 in RATES_C_PER_S:
        warped = [warped_temperature(p.time_s, d, r0) for p, d in zip(selector.runs, drive,
                                                                      strict=True)]
        for w in WIDTHS_C:
            states = [hysteresis_state(tw, direction_state(tw, w), w) for tw in warped]
            ev = evaluate_with(selector, rest, others,
                               extra={"hysteresis": _column(states, index)})
            if best is None or ev.heldout_rms_dps < best[0].heldout_rms_dps:
                best = (ev, w, r0)
    assert best is not None
    ev, w, r0 = best
    ev = replace(ev, k=ev.k + 2)  # w and r₀ were searched
    if not enters(without, ev, margin=margin, n_runs=len(selector.runs)):
        return None
    if with_structure.heldout_rms_dps * (1.0 + margin) <= ev.heldout_rms_dps:
        return None
    return RateWidth(w, r0, ev.heldout_rms_dps, without.heldout_rms_dps,
                     with_structure.heldout_rms_dps)
