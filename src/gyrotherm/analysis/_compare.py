"""Measured against simulated: residual statistics over several simulator replays.

The simulator is calibrated to the runs (:mod:`.simcal._simulate`): its noise
(white, Gauss–Markov, switch-on offsets) once, on the residuals of the
extended model — the paper model's residuals hold any effect it misses, which
a noise fit would absorb (a drift becomes a slow Gauss–Markov process) and so
hide from the comparison; with nothing found the two are the same. It
replays the runs' temperature histories ``replays`` times with zero bias,
replay k with seed ``seed + 100 000·k`` (k = 0 is the replay the report
plots), and each model's bias (paper, extended) is added to the same replay,
so the models see identical noise. The paper model is refitted to every
replay exactly as to the measured runs, and the statistics of :mod:`._stats`
are computed on each. For every statistic:

* ``measured`` m; ``simulated``: replay 0's value (paper model);
* ``sim_mean``, ``sim_std``: mean and sample standard deviation (ddof 1) over
  the n = ``replays`` replays;
* ``z`` = (m − sim_mean)/sim_std, and ``significant`` when
  |z| > :func:`._stats.z_threshold` (n) — outside the 99.73 % prediction
  interval of one more replay (Student's t, n − 1 degrees of freedom; 7.25 for
  n = 5). With K statistics, a simulator that is right marks a given one with
  probability 0.0027, any one with ≤ K·0.0027 (0.038 for K = 14) and two with
  ≤ K(K − 1)/2·0.0027² (7·10⁻⁴) if they were independent;
* the same for the extended model (``simulated_extended`` = its replay 0,
  ``extended_mean``, ``extended_std``, ``extended_z``,
  ``extended_significant``): whether modelling the effects closes the gap.

The list is ordered by |z|, largest first. |z| measures how surely a
statistic differs, not how much: a large missed effect moves most statistics
(a drift also raises the residual RMS and its correlation time), and with long
runs small differences in the noise's shape become significant too (the
simulator's noise is white + one Gauss–Markov process). A statistic that is
NaN in the measured runs or in any paper-model replay is left out, with the
reason in :attr:`SimulationComparison.notes` (one NaN in an extended replay
keeps its paper-model fields and has no extended ones).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from gyrotherm._errors import ConfigError
from gyrotherm.analysis._effects import add_bias
from gyrotherm.analysis._prep import Prepared, Readout, characterise, estimator_for, prepare
from gyrotherm.analysis._score import Selector
from gyrotherm.analysis._stats import (
    gauss_markov_fit,
    replay_spread,
    residual_statistics,
    statistic_requirement,
    z_score,
    z_threshold,
)
from gyrotherm.analysis.simcal._simulate import SimCalibration, calibrate, replay_noise
from gyrotherm.codecs import Run
from gyrotherm.compensation import Scaling

if TYPE_CHECKING:
    from gyrotherm.analysis._diagnose import Diagnosis

DEFAULT_REPLAYS = 5
SEED_STRIDE = 100_000
MIN_REPLAYS = 2


@dataclass(frozen=True)
class Mismatch:
    """One statistic, measured against the replays (see the module docstring)."""

    statistic: str
    measured: float
    simulated: float
    simulated_extended: float | None = None
    sim_mean: float = math.nan
    sim_std: float = math.nan
    z: float = math.nan
    significant: bool = False
    extended_mean: float | None = None
    extended_std: float | None = None
    extended_z: float | None = None
    extended_significant: bool | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"statistic": self.statistic, "measured": self.measured,
                               "simulated": self.simulated}
        if self.simulated_extended is not None:
            out["simulated_extended"] = self.simulated_extended
        out.update(sim_mean=self.sim_mean, sim_std=self.sim_std, z=self.z,
                   significant=self.significant)
        if self.extended_z is not None:
            out.update(extended_mean=self.extended_mean, extended_std=self.extended_std,
                       extended_z=self.extended_z, extended_significant=self.extended_significant)
        return out


@dataclass(frozen=True)
class SimulationComparison:
    """The calibrated simulator, replay 0 of both models, and the mismatch list."""

    calibration: SimCalibration
    runs: tuple[Run, ...]
    prepared: tuple[Prepared, ...]
    residuals: tuple[np.ndarray, ...]
    extended_runs: tuple[Run, ...]
    extended_prepared: tuple[Prepared, ...]
    mismatch: tuple[Mismatch, ...]
    replays: int = 1
    z_threshold: float = math.nan
    omitted: tuple[tuple[str, str], ...] = field(default_factory=tuple)
    """(statistic, reason) for each statistic left out of :attr:`mismatch`."""

    @property
    def significant(self) -> tuple[Mismatch, ...]:
        return tuple(m for m in self.mismatch if m.significant)

    @property
    def notes(self) -> tuple[str, ...]:
        return tuple(f"simulation: statistic {name} left out of the mismatch list: {why}"
                     for name, why in self.omitted)

    def to_dict(self) -> dict[str, Any]:
        return {
            "mismatch": [m.to_dict() for m in self.mismatch],
            "calibration": self.calibration.to_dict(),
            "replays": self.replays,
            "z_threshold": self.z_threshold,
            "significant": [m.statistic for m in self.significant],
            "omitted": [{"statistic": s, "reason": r} for s, r in self.omitted],
        }


def statistics_for(
    prepared: Sequence[Prepared], scaling: Scaling, readouts: Sequence[Readout]
) -> tuple[dict[str, float], list[np.ndarray], list[float]]:
    """Statistics of the paper-model residual of ``prepared`` (one offset per run)."""
    sel = Selector(prepared, scaling)
    ev = sel.evaluate({})
    raw = sel.residuals_raw(ev)
    offsets = [float(r.mean()) for r in raw]
    resid = [r - r.mean() for r in raw]
    arw = float(np.median([r.sample_noise_dps * 60.0 / math.sqrt(r.sample_rate_hz)
                           for r in readouts]))
    return residual_statistics(prepared, resid, arw_deg_per_rth=arw, offsets_dps=offsets), \
        resid, offsets


@dataclass(frozen=True)
class _Replays:
    runs: list[Run]
    prepared: list[Prepared]
    residuals: list[np.ndarray]
    stats: list[dict[str, float]]

    def values(self, name: str) -> list[float]:
        return [s.get(name, math.nan) for s in self.stats]


def _scored(name: str, m: float, base: _Replays, ext: _Replays) -> Mismatch | str:
    """The statistic's mismatch, or why it is left out."""
    values = base.values(name)
    mean, std, n = replay_spread(values)
    if n < len(values):
        return (f"not defined in {len(values) - n} of {len(values)} replays of the simulator "
                f"(it needs {statistic_requirement(name)})")
    z = z_score(m, mean, std)
    ext_values = ext.values(name)
    emean, estd, en = replay_spread(ext_values)
    complete = en == len(ext_values)
    ez = z_score(m, emean, estd) if complete else math.nan
    return Mismatch(
        statistic=name, measured=m, simulated=values[0],
        simulated_extended=ext_values[0] if complete else None,
        sim_mean=mean, sim_std=std, z=z, significant=bool(abs(z) > z_threshold(n)),
        extended_mean=emean if complete else None,
        extended_std=estd if complete else None,
        extended_z=ez if complete else None,
        extended_significant=bool(abs(ez) > z_threshold(en)) if complete else None,
    )


def compare_simulation(
    runs: Sequence[Run],
    readouts: Sequence[Readout],
    diagnosis: Diagnosis,
    *,
    est_tau: float,
    self_heating_c: float,
    seed: int = 0,
    replays: int = DEFAULT_REPLAYS,
    features: str = "smooth",
) -> SimulationComparison:
    """Calibrate the simulator, replay baseline and extended models ``replays`` times
    each, and score every statistic against the replays' spread."""
    if replays < MIN_REPLAYS:
        raise ConfigError(f"diagnose: replays = {replays!r} is below {MIN_REPLAYS}: the "
                          "replays' spread needs at least 2 of them")
    axis = diagnosis.axis
    scaling = diagnosis.baseline.scaling
    measured, resid, offsets = statistics_for(diagnosis.prepared, scaling, readouts)

    def calibrated(residuals: Sequence[np.ndarray]) -> SimCalibration:
        sigma, tau_gm = gauss_markov_fit(residuals)
        return calibrate(readouts, axis=axis, tau_s=est_tau, self_heating_c=self_heating_c,
                         tau_from_chamber=diagnosis.tau_from_chamber, gm_sigma_dps=sigma,
                         gm_tau_s=tau_gm, offsets_dps=offsets)

    has_ext = bool(diagnosis.extended.effects)
    # one noise calibration for both models, on the extended model's residuals: the
    # paper model's residuals hold any effect it misses, which a noise fit absorbs
    # (a drift becomes a slow Gauss–Markov process) and so hides from the comparison
    cal = calibrated(diagnosis.extended_residuals if has_ext else resid)
    models = (diagnosis.baseline, diagnosis.extended) if has_ext else (diagnosis.baseline,)
    reps = [_Replays([], [], [], []) for _ in models]
    for k in range(replays):
        noise = replay_noise(runs, diagnosis.prepared, cal, axis=axis,
                             seed=seed + SEED_STRIDE * k)
        for model, out in zip(models, reps, strict=True):
            sims = [add_bias(r, model, axis) for r in noise]
            sim_ro = [characterise(r, axis) for r in sims]
            est = estimator_for(sim_ro, est_tau)
            preps = [prepare(r, axis, est, features=features) for r in sims]
            stats, res, _ = statistics_for(preps, scaling, sim_ro)
            if k == 0:
                out.runs.extend(sims)
                out.prepared.extend(preps)
                out.residuals.extend(res)
            out.stats.append(stats)
    base, ext = reps[0], reps[-1]
    scored: list[Mismatch] = []
    omitted: list[tuple[str, str]] = []
    for name, m in measured.items():
        if not math.isfinite(m):
            omitted.append((name, f"not defined on the measured runs (it needs "
                                  f"{statistic_requirement(name)})"))
            continue
        got = _scored(name, m, base, ext)
        if isinstance(got, str):
            omitted.append((name, got))
        else:
            scored.append(got)
    scored.sort(key=lambda x: -abs(x.z) if math.isfinite(x.z) else math.inf)
    return SimulationComparison(
        cal, tuple(base.runs), tuple(base.prepared), tuple(base.residuals),
        tuple(ext.runs), tuple(ext.prepared), tuple(scored), replays=replays,
        z_threshold=z_threshold(replays), omitted=tuple(omitted))

