"""Whether a ``warmup`` beside a ``hysteresis`` is the hysteresis' first branch.

The catalogued hysteresis (:func:`~._effects.direction_state`,
:func:`~._effects.hysteresis_state`) is 0 from power-on until the temperature has moved
one transition width w beyond its extreme, and only then turns towards ±1. A material
whose state follows the temperature at once (a stop operator, h ← clip(h + 2·dT/w, −1, 1)
from 0) moves already while the die warms itself in the first hold after power-on. The
difference lives in the first minutes, before the first ramp, and decays with time since
power-on there: a warm-up A·e^(−t/τ) beside the hysteresis follows it, and is named
although no warm-up exists (round 6 of issue 19: shapes-dev2 seed 46 at 0.125 °C, the
residual without the warm-up −15 to −26 m°/s over 100–600 s while self-heating raised the
die ~1.3 °C, and ~0 once the ramp started).

So a warm-up beside a hysteresis is weighed against the *first branch*: one column that
follows the temperature from power-on, clip((T − T(0))/w, −1, 1), until the catalogued
state first turns, and then relaxes from its last value as e^(−travel/w) (travel: the
temperature's path length since that turn), w the hysteresis' fitted width, T the
temperature the hysteresis sees (lagged with a coupled ``thermal_lag``). When that column
in the warm-up's place is at least as good held out and better on at least half of the
left-out runs, the warm-up is left out ("the hysteresis' first branch", with both RMS).
A warm-up decays with time whether the temperature moves or not; the first branch
moves with the temperature: on development seeds with a real warm-up beside a real
hysteresis the warm-up beat the column by ×2.0–2.9 on every left-out run (dev seeds 1–4
at 0.125 °C), while the false warm-up lost to it by ×1.08 on 4/4.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._effects import direction_state, lowpass
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._resolve import NotResolvable
from gyrotherm.analysis._score import Evaluation, Selector
from gyrotherm.analysis._unexplained import evaluate_with
from gyrotherm.compensation._effects import MIN_TRANSITION_C

FloatArray = NDArray[np.float64]

FIRST_BRANCH_VERDICT = "the hysteresis' first branch"


def first_branch(temperature_c: FloatArray, width_c: float) -> FloatArray:
    """The first-branch column (module docstring) of a temperature series (1-s blocks)."""
    t = np.asarray(temperature_c, dtype=np.float64)
    out = np.zeros(len(t))
    if len(t) == 0:
        return out
    turned = np.flatnonzero(direction_state(t, width_c) != 0.0)
    k = int(turned[0]) if len(turned) else len(t)
    out[:k] = np.clip((t[:k] - t[0]) / width_c, -1.0, 1.0)
    if k < len(t):
        travel = np.cumsum(np.abs(np.diff(t[k:], prepend=t[k])))
        out[k:] = out[k - 1] * np.exp(-travel / width_c)  # k ≥ 1: no turn at sample 0
    return out


def _hysteresis_temperature(selector: Selector, effects: dict[str, float],
                            p: Prepared) -> FloatArray:
    lag = effects.get("thermal_lag", 0.0) if selector.coupled else 0.0
    if lag:
        return np.asarray(lowpass(p.temperature_c, round(lag, 6), step_s=1.0),
                          dtype=np.float64)
    return np.asarray(p.temperature_c, dtype=np.float64)


def drop_warmup_like_first_branch(
    selector: Selector, final: Evaluation
) -> tuple[Evaluation, NotResolvable | None]:
    """``final`` without its ``warmup`` (the others refitted) and the verdict, when the
    hysteresis' first branch in its place is at least as good held out (module
    docstring); else ``final`` and None."""
    from gyrotherm.analysis._select import _compare, _refine_all

    if not {"warmup", "hysteresis"} <= set(final.effects):
        return final, None
    effects = dict(final.effects)
    width = max(effects["hysteresis"], MIN_TRANSITION_C)
    rest = {k: v for k, v in effects.items() if k != "warmup"}
    base = evaluate_with(selector, effects, [])
    alt = evaluate_with(selector, rest, [], extra={"first_branch": lambda p: first_branch(
        _hysteresis_temperature(selector, effects, p), width)})
    ratio, improved, _ = _compare(base, alt)  # > 1: the first branch is better
    if ratio < 1.0 or improved < math.ceil(len(selector.runs) / 2):
        return final, None
    without = _refine_all(selector, selector.evaluate(rest))
    reason = (f"the hysteresis' first branch (its state following the temperature from "
              f"power-on, width {width:.2f} °C, until it first turns) in its place is as good "
              f"held out (RMS {alt.heldout_rms_dps:.5f} against {base.heldout_rms_dps:.5f} °/s, "
              f"×{ratio:.3f}, better on {improved}/{len(selector.runs)} left-out runs): what "
              "the warm-up follows moves with the die's self-heating after power-on, not with "
              f"time alone; held-out RMS without it {without.heldout_rms_dps:.5f} vs "
              f"{final.heldout_rms_dps:.5f} °/s")
    params = {"tau_s": float(effects["warmup"]), "transition_c": width, "ratio": ratio}
    return without, NotResolvable("warmup", params, reason, verdict=FIRST_BRANCH_VERDICT)
