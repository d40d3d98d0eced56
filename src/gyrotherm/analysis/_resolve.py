"""What the diagnosis' temperature estimate can resolve in time.

A ``thermal_lag`` of time constant τ delays the temperature the bias sees.
Its first-order part, τ·dT/dt, is absorbed by the ΔT terms; what identifies a
lag is its shape after each ramp corner, which lasts ≈ τ. The temperature
feature cannot show timing finer than the largest of

* the readout's update period P (a reading is held for P),
* the time the ramps need to cross one readout LSB q, q / |dT/dt|, with
  |dT/dt| the median rate over the blocks whose |dT/dt| exceeds
  :data:`~._stats.RATE_THRESHOLD_C_PER_S` (a quantised reading changes only
  once per LSB crossed),
* half the window of the zero-phase smoother of ``features="smooth"``
  (:data:`SMOOTH_T_WINDOW_S` / 2; 1-s blocks for ``"kalman"``).

τ_min = max of these. A lag fitted below τ_min is not a physical finding (the
fit found timing the readout cannot show): it is left out of the model and
named in the notes with the limit and its reason.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrotherm.analysis._prep import BLOCK_S, Prepared, Readout
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._stats import RATE_THRESHOLD_C_PER_S

SMOOTH_T_WINDOW_S = 31.0
"""Window (s) of the Savitzky–Golay fit that gives T in :func:`~._prep.prepare`."""


@dataclass(frozen=True)
class LagLimit:
    """τ_min (s) and its three candidates."""

    hold_s: float
    lsb_crossing_s: float
    smoother_s: float

    @property
    def tau_min_s(self) -> float:
        return max(self.hold_s, self.lsb_crossing_s, self.smoother_s)

    def reason(self) -> str:
        parts = {"readout hold period": self.hold_s,
                 "time to cross one readout LSB on the ramps": self.lsb_crossing_s,
                 "half the temperature smoother's window": self.smoother_s}
        which = max(parts, key=lambda k: parts[k])
        return f"τ_min = {self.tau_min_s:.1f} s, set by the {which}"


def lag_limit(
    readouts: Sequence[Readout], runs: Sequence[Prepared], *, features: str = "smooth"
) -> LagLimit:
    """τ_min for these readouts and runs (module docstring)."""
    hold = float(np.median([r.period_s for r in readouts]))
    lsb = float(np.median([r.lsb_c for r in readouts]))
    rate = np.abs(np.concatenate([p.rate_c_per_s for p in runs]))
    ramp = rate[rate > RATE_THRESHOLD_C_PER_S]
    crossing = lsb / float(np.median(ramp)) if len(ramp) and lsb > 0 else 0.0
    smoother = SMOOTH_T_WINDOW_S / 2.0 if features == "smooth" else BLOCK_S
    return LagLimit(hold_s=hold, lsb_crossing_s=crossing, smoother_s=smoother)


def drop_unresolved_lag(
    selector: Selector, final: Evaluation, limit: LagLimit
) -> tuple[Evaluation, str | None]:
    """``final`` without its ``thermal_lag`` when τ < τ_min (the others refitted), and
    the note saying so; ``final`` and None otherwise."""
    from gyrotherm.analysis._select import _refine_all

    tau = final.effects.get("thermal_lag")
    if tau is None or tau >= limit.tau_min_s:
        return final, None
    rest = {k: v for k, v in final.effects.items() if k != "thermal_lag"}
    without = _refine_all(selector, selector.evaluate(rest))
    note = (f"thermal_lag with τ = {tau:.1f} s not reported: below what the temperature "
            f"readout can resolve ({limit.reason()}; hold {limit.hold_s:.2f} s, LSB crossing "
            f"{limit.lsb_crossing_s:.1f} s, smoother {limit.smoother_s:.1f} s); held-out RMS "
            f"without it {without.heldout_rms_dps:.5f} vs {final.heldout_rms_dps:.5f} °/s")
    return without, note
