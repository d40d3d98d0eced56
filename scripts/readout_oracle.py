"""What the readout lets any method see of an injected shape: the oracle gain.

For a diagnosis of generated runs, the injected off-catalogue shapes' own formula
(:func:`~gyrotherm.analysis.synth._variants.shape_bias`) with their *true*
parameters, evaluated on the readout's estimates the diagnosis used (the 1-s
blocks' temperature, ΔT and time since power-on, not the generator's true die
temperature and gradient), is added as one column to the paper model, one offset
per run, and scored leave-one-run-out on the same blocks as the diagnosis
(:mod:`gyrotherm.analysis._score`). Its held-out gain over the paper model alone is
the most a method that reads these variables could buy: it knows the shape and
its parameters and fits only the amplitude. A shape missed where this is below the
diagnosis' selection margin (×1.10) is below what the readout shows; one missed
above it is the method's miss.

    from readout_oracle import oracle_gain
    gain = oracle_gain(truth.shapes, diagnosis.prepared, diagnosis.baseline.scaling)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from gyrotherm.analysis._effects import design
from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._score import solve, sse
from gyrotherm.analysis.synth._variants import shape_bias
from gyrotherm.compensation import Scaling


def heldout_gain(runs: Sequence[Prepared], scaling: Scaling,
                 column: Sequence[np.ndarray], *,
                 effects: Mapping[str, float] | None = None) -> float:
    """Paper model's held-out RMS over that of the paper model plus ``column`` (one
    array per run), one offset per run, leave-one-run-out (≥ 2 runs). ``effects``
    (name → nonlinear parameter): the catalogued effects added to the paper model in
    both, e.g. a diagnosis' chosen model."""
    rms = []
    for extra in (False, True):
        mats = []
        for p, c in zip(runs, column, strict=True):
            _, x = design(p.time_s, p.temperature_c, p.delta_t_c, scaling, effects or {})
            if extra:
                x = np.column_stack([x, c])
            z = x - x.mean(axis=0)
            zy = np.column_stack([z, p.rate_dps - p.rate_dps.mean()])
            mats.append(zy.T @ zy)
        m = np.array(mats)
        total = m.sum(axis=0)
        held = sum(sse(m[r], solve(total - m[r])) for r in range(len(m)))
        rms.append(math.sqrt(held / sum(len(p) for p in runs)))
    return rms[0] / rms[1]


def oracle_gain(shapes: Mapping[str, Mapping[str, float]], runs: Sequence[Prepared],
                scaling: Scaling, *, effects: Mapping[str, float] | None = None
                ) -> float | None:
    """The oracle gain (module docstring) of ``shapes`` (name → true parameters) on the
    diagnosis' prepared ``runs``; None when nothing off-catalogue was injected.
    ``effects``: over the paper model with these catalogued effects instead (the gain
    the shape has left over a diagnosis' chosen model, which its detection floor is
    relative to)."""
    if not shapes:
        return None
    column = [sum((shape_bias(name, params, p.time_s, p.temperature_c, p.delta_t_c)
                   for name, params in shapes.items()), np.zeros(len(p))) for p in runs]
    return heldout_gain(runs, scaling, column, effects=effects)
