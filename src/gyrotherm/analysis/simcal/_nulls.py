"""Null comparisons for the simulator calibration (docs/findings.md §7).

Each calibrated parameter is scored on held-out statistics at its fitted value and at
its nulls: the simulator's default, zero, and (signed parameters only) the fitted
value with its sign flipped. For each null the parameter is held at the null value
and everything fitted after it is refitted on the fit set, so the comparison is
between two calibrations that differ only in that parameter. Nothing is chosen on the
held-out set: the fitted value is kept or reverted to the default, never replaced by
a null that scores better.

Rule, fixed before scoring: with E_s the mean held-out error of seed group s (the
same seeds for every candidate), the fitted value is kept if, against every null,
the paired difference d_s = E_s(null) − E_s(fitted) has mean > 2 standard errors
(std(d, ddof 1)/√n) and > 0.01 (1 % on the log-ratio errors: paired seeds cancel the
simulation noise, so a negligible but systematic effect can exceed 2 SE). A tie (no
effect, or a difference within the seeds' spread) is not kept.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gyrotherm.analysis.simcal._calibrate import (
    DEFAULTS,
    PARAMETERS,
    TangFit,
    fit_tang,
    held_out_error,
    score_tang,
    spread_default,
)

#: the margin, in standard errors of the paired difference, a fitted value must have
#: over every null to be kept
MARGIN_SE = 2.0
#: the smallest mean difference (held-out error units) that counts as beating a null
MIN_MARGIN = 0.01
#: Tang's parameters that change sign meaningfully (amplitudes and stds do not)
TANG_SIGNED: frozenset[str] = frozenset({"dt_scale", "bow_rate_exponent"})


@dataclass(frozen=True)
class Trial:
    """One value of a parameter and its mean held-out error per seed group."""

    label: str
    """"fitted", "default", "zero", "default = zero" or "flipped"."""
    value: float
    errors: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.errors))

    @property
    def spread(self) -> float:
        """std of the seed groups' errors (ddof 1)."""
        return float(np.std(self.errors, ddof=1)) if len(self.errors) > 1 else 0.0


@dataclass(frozen=True)
class NullTest:
    """A fitted parameter against its nulls."""

    parameter: str
    fitted: Trial
    nulls: tuple[Trial, ...]

    def margin(self, null: Trial) -> tuple[float, float]:
        """(mean, standard error) of the paired d_s = E_s(null) − E_s(fitted)."""
        d = np.subtract(null.errors, self.fitted.errors)
        se = float(np.std(d, ddof=1) / math.sqrt(len(d))) if len(d) > 1 else 0.0
        return float(np.mean(d)), se

    @property
    def kept(self) -> bool:
        """The fitted value beats every null by more than :data:`MARGIN_SE` SEs and
        :data:`MIN_MARGIN`."""
        return all(m > max(MARGIN_SE * se, MIN_MARGIN) for m, se in map(self.margin, self.nulls))


def null_values(fitted: float, default: float, *, signed: bool) -> list[tuple[str, float]]:
    """The nulls of a parameter: default, zero, and −fitted when ``signed``."""
    out = [("default = zero", 0.0)] if default == 0 else [("default", default), ("zero", 0.0)]
    if signed and fitted != 0:
        out.append(("flipped", -fitted))
    return out


def run_null_tests(fitted: Mapping[str, float], defaults: Mapping[str, float],
                   signed: Collection[str], fitted_errors: Mapping[str, Sequence[float]],
                   evaluate: Callable[[str, float], Sequence[float]]) -> list[NullTest]:
    """One :class:`NullTest` per parameter of ``fitted`` (per-seed-group errors at the
    fitted values: ``fitted_errors[name]``); ``evaluate(name, value)`` returns the
    per-seed-group held-out errors with ``name`` held at ``value``."""
    out = []
    for name, value in fitted.items():
        nulls = tuple(Trial(label, v, tuple(evaluate(name, v)))
                      for label, v in null_values(value, defaults[name],
                                                  signed=name in signed))
        out.append(NullTest(name, Trial("fitted", value, tuple(fitted_errors[name])), nulls))
    return out


def tang_group_errors(fit: TangFit, groups: Sequence[Sequence[int]]) -> list[float]:
    """Mean held-out Tang error of ``fit`` per seed group."""
    return [held_out_error(score_tang(fit.gyro, fit.chamber, seeds=g)) for g in groups]


def tang_null_tests(fit: TangFit, *, fit_seeds: Sequence[int],
                    groups: Sequence[Sequence[int]],
                    context: Mapping[str, float] | None = None) -> list[NullTest]:
    """Null comparisons of the calibration ``fit`` (hypothesis ``fit.hypothesis``).

    ``context``: parameters held at these values for the others' tests (the profile's
    reverted values); each tested parameter is then refitted in that context. Without
    it the others are as in ``fit``."""
    defaults = {**DEFAULTS, "spread": spread_default(fit.hypothesis)}
    names = [p for p in PARAMETERS if p != "spread" or fit.hypothesis != "none"]

    def fixed(name: str) -> dict[str, float]:
        return {k: v for k, v in (context or {}).items() if k != name}

    def evaluate(name: str, value: float) -> list[float]:
        refit = fit_tang(fit_seeds=fit_seeds, hypothesis=fit.hypothesis,
                         fixed={**fixed(name), name: value})
        return tang_group_errors(refit, groups)

    fitted, errors = {}, {}
    base = tang_group_errors(fit, groups) if context is None else None
    for name in names:
        own = fit if context is None else fit_tang(fit_seeds=fit_seeds,
                                                    hypothesis=fit.hypothesis,
                                                    fixed=fixed(name))
        fitted[name] = own.values[name]
        errors[name] = base if base is not None else tang_group_errors(own, groups)
    return run_null_tests(fitted, defaults, TANG_SIGNED, errors, evaluate)


__all__ = ["MARGIN_SE", "MIN_MARGIN", "NullTest", "Trial", "null_values", "run_null_tests",
           "tang_group_errors", "tang_null_tests"]
