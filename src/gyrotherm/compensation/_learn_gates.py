"""The learning's thresholds, without its numerics: what the daemon's config check
(:mod:`gyrotherm.daemon._learn_config`) needs, so that a daemon without ``[learn]``
never loads :mod:`._learn` or :mod:`._learnstate` (``bench/footprint.py``: every module
on the vehicle path is resident memory)."""

from __future__ import annotations

#: Rows of a warm-up used: after SETTLE_S (the estimator's ΔT converging) and at most
#: WARMUP_MAX_S after power-on, at rest, until the first row in motion.
SETTLE_S = 10.0
WARMUP_MAX_S = 1800.0
#: Named adoption gates (thresholds in the names' units).
GATES = {"min_warmups": 3, "min_start_span_c": 8.0, "max_condition": 1e8}
ADOPT_MARGIN = 0.10
"""The candidate's held-out RMS must be ≤ (1 − margin) × the current one's, every axis."""

__all__ = ["ADOPT_MARGIN", "GATES", "SETTLE_S", "WARMUP_MAX_S"]
