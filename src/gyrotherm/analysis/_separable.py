"""Whether a ``drift`` can be told apart from the ``warmup`` next to it.

Both are functions of time since power-on only. A drift s·t is identified by
the trend that remains once the warm-up A·e^(−t/τ) has died away: after 3τ it
is below 5 % of A. When less than half of the runs lies beyond 3τ
(τ > duration / 6), the two share one smooth, monotone stretch of each run
and trade off against each other: a long warm-up plus a drift fits any slow
transient (a logistic or two-exponential warm-up, a slow thermal settling)
whatever the drift is. Such a drift is reported as not resolvable in these
runs (:class:`~._resolve.NotResolvable`, with τ, the runs' duration and what
would resolve it: runs longer than 6τ) and left out of the model; the warm-up
is refitted without it, and what the single exponential then leaves is for
the unexplained search (:mod:`._unexplained`) to name.
"""

from __future__ import annotations

import numpy as np

from gyrotherm.analysis._resolve import NotResolvable
from gyrotherm.analysis._score import Evaluation, Selector

DECAYED_TAUS = 3.0
"""A warm-up has decayed (below e^(−3) ≈ 5 % of its amplitude) after this many τ."""
MIN_DECAYED_SHARE = 0.5
"""The share of the runs' duration that must lie beyond DECAYED_TAUS·τ."""
RUNS_VERDICT = "not resolvable in these runs"


def drop_inseparable_drift(
    selector: Selector, final: Evaluation
) -> tuple[Evaluation, NotResolvable | None]:
    """``final`` without its ``drift`` (refitted) and the verdict, when a ``warmup`` in
    the model has not decayed over at least half of the runs (module docstring)."""
    from gyrotherm.analysis._select import _refine_all

    if not {"drift", "warmup"} <= set(final.effects):
        return final, None
    tau = float(final.effects["warmup"])
    duration = float(np.median([p.time_s[-1] - p.time_s[0] for p in selector.runs]))
    decayed = max(0.0, duration - DECAYED_TAUS * tau) / duration
    if decayed >= MIN_DECAYED_SHARE:
        return final, None
    rest = {k: v for k, v in final.effects.items() if k != "drift"}
    without = _refine_all(selector, selector.evaluate(rest))
    slope = float(selector.model(final).params()["drift"]["slope_dps_per_h"])
    reason = (f"next to a warm-up of τ = {tau:.0f} s the runs ({duration:.0f} s) have "
              f"{100 * decayed:.0f} % of their length beyond 3τ (warm-up below 5 %), less "
              f"than {100 * MIN_DECAYED_SHARE:.0f} %: a drift cannot be told from the "
              f"warm-up's tail (runs longer than {2 * DECAYED_TAUS * tau:.0f} s would "
              f"resolve it); held-out RMS without it {without.heldout_rms_dps:.5f} vs "
              f"{final.heldout_rms_dps:.5f} °/s")
    params = {"slope_dps_per_h": slope, "warmup_tau_s": tau, "duration_s": duration}
    return without, NotResolvable("drift", params, reason, verdict=RUNS_VERDICT)
