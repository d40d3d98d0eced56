"""Analysis: diagnose which physical effect a bias model and the simulator miss.

:func:`diagnose` fits the paper model to measured runs, replays their
temperature histories through the calibrated simulator, tests candidate
effects (:data:`EFFECTS`) with leave-one-run-out validation and a penalised
criterion, and reports a :class:`Diagnosis` (JSON schema
``gyrotherm.diagnosis/1``); :func:`write_report` adds a Markdown report with
plots. :func:`synth_runs` is an independent generator (two-node thermal
network, quantised slow readout, Gauss–Markov noise) for testing it.

Three rooms: the diagnosis here (``_diagnose``, ``_select``, ``_effects``,
``_unexplained``, ``_where``, ``_shape_check``, the readout verdicts ``_null_replay``,
``_resolve``, ``_resolution``, ``_separable``, ``_intervals``; ``_to_calibration``
turns a diagnosis into a calibration); the synthetic generator the diagnosis is tested
on (:mod:`.synth`); the simulator calibrated to measured runs and its replay
(:mod:`.simcal`).
"""

from gyrotherm.analysis._compare import Mismatch, SimulationComparison
from gyrotherm.analysis._diagnose import SCHEMA, Diagnosis, Finding, diagnose
from gyrotherm.analysis._effects import (
    EFFECTS,
    ExtendedModel,
    add_bias,
    direction_state,
    lowpass,
)
from gyrotherm.analysis._report import write_report
from gyrotherm.analysis._stats import allan_deviation
from gyrotherm.analysis.synth._synth import (
    SYNTH_EFFECTS,
    SynthConfig,
    SynthTruth,
    synth_run,
    synth_runs,
)

__all__ = [
    "EFFECTS",
    "SCHEMA",
    "SYNTH_EFFECTS",
    "Diagnosis",
    "ExtendedModel",
    "Finding",
    "Mismatch",
    "SimulationComparison",
    "SynthConfig",
    "SynthTruth",
    "add_bias",
    "allan_deviation",
    "diagnose",
    "direction_state",
    "lowpass",
    "synth_run",
    "synth_runs",
    "write_report",
]
