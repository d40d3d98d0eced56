"""Held-out evaluation of the diagnosis' false alarms (issue 19, item 1).

EVAL_SEEDS are fixed here and in scripts/generalisation_sweep.py before any
result on them was seen; they are never used while developing the guards."""

from __future__ import annotations

EVAL_SEEDS = (101, 102, 103, 104, 105)
DEV_SEEDS = (1, 2, 3, 4, 5, 6)


def test_eval_seeds_are_disjoint_from_development_seeds() -> None:
    assert not set(EVAL_SEEDS) & set(DEV_SEEDS)
