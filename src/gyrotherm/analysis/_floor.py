"""What the diagnosis could not have seen: its detection floor in each variable.

A structure in v ∈ :data:`~._unexplained.VARIABLES` (T, ΔT, time since power-on) is
reported only when a spline in v gains, held out over the chosen model, at least
1 + margin (:func:`~._unexplained.search_unexplained`) and at least (1 + margin)·N_v,
N_v the largest gain a spline in v buys on :data:`~._resolve.NULL_REPLAYS` readout
replays of that model without any structure (:func:`~._resolve.readout_structure`,
:func:`~._null_replay.replay_splines`). So whatever its shape, a structure in v whose
best possible held-out gain is below

    F_v = (1 + margin) · max(1, N_v)

is not reported: at this readout it is not resolvable, and the diagnosis says so for
every structure below F_v at once instead of naming none. (The gain a structure is
admitted at is over the model the search tried it on; when it makes a catalogued effect
redundant, that effect is dropped and its reported gain, over the refitted model, can be
lower than F_v.) In amplitude: a structure of RMS s (°/s) on top of residuals of
held-out RMS R gains about √(1 + s²/R²), so F_v is a structure of about R·√(F_v² − 1)
°/s RMS (approximate: held out, the structure's fit costs some of it).

A catalogued effect is selected at a held-out gain of at least 1 + margin over the model
(:mod:`._select`), the same floor without replays; a lag and a hysteresis must also pass
their own readout replays (:mod:`._resolve`), stated in their verdicts when selected.

The floor is a claim the sweep checks against the truth (``scripts/generalisation_sweep.py``):
an injected structure the diagnosis missed whose oracle gain (its true shape fitted,
``scripts/readout_oracle.py``), over the paper model and over the chosen model both, is
below F_v was declared by the floor; one missed above F_v is a plain miss; one reported in
its variable below F_v means the floor overstates what the readout hides.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from gyrotherm.analysis._null_replay import replay_splines
from gyrotherm.analysis._prep import Readout
from gyrotherm.analysis._score import Selector


@dataclass(frozen=True)
class Floor:
    """The smallest held-out gain over the model a structure in ``variable`` must have to
    be reported (module docstring)."""

    variable: str
    gain: float
    """F_v = (1 + margin)·max(1, null_gain)."""
    null_gain: float
    """N_v: the largest gain readout replays without a structure give a spline in it."""
    rms_dps: float
    """About how large (°/s RMS) a structure gaining F_v is: R·√(F_v² − 1)."""
    margin: float

    def to_dict(self) -> dict[str, Any]:
        return {"variable": self.variable, "gain": self.gain, "null_gain": self.null_gain,
                "rms_dps": self.rms_dps, "margin": self.margin}


def detection_floors(
    selector: Selector, effects: Mapping[str, float], readouts: Sequence[Readout],
    crossing_s: float, heldout_rms_dps: float, variables: Sequence[str], *,
    margin: float = 0.10, seed: int = 0, replays: int = 2,
    unresolved: Mapping[str, float] | None = None,
) -> tuple[Floor, ...]:
    """F_v for each of ``variables`` on top of the chosen model ``effects`` (held-out RMS
    ``heldout_rms_dps``), from the same readout replays :func:`~._resolve.readout_structure`
    makes (``seed``, ``replays``, ``unresolved``: the effects left out by a verdict, in
    the replays' generating model)."""
    gains, _ = replay_splines(selector, dict(effects), readouts, crossing_s, variables,
                              seed=seed, replays=replays, unresolved=unresolved)
    floors = []
    for v in variables:
        null = max(gains[v])
        gain = (1.0 + margin) * max(1.0, null)
        floors.append(Floor(variable=v, gain=gain, null_gain=null,
                            rms_dps=heldout_rms_dps * math.sqrt(gain * gain - 1.0),
                            margin=margin))
    return tuple(floors)
