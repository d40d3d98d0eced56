"""Shared by the fast-path tests (tests/readers/test_fast_*.py): the real-log corpus and
a bit-for-bit comparison of two readings of one file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from gyrotherm.codecs import Run
from gyrotherm.readers._common import FALLBACK_KEY

ROOT = Path(__file__).resolve().parents[1]


def corpus_dir() -> Path | None:
    """The real-log corpus, found as tests/cli/test_reallogs.py finds it."""
    candidates = [os.environ.get("GYROTHERM_REALLOGS", ""),
                  str(ROOT.parent / "shared" / "data" / "reallogs"),
                  "/work/shared/data/reallogs"]
    return next((Path(c) for c in candidates if c and (Path(c) / "SOURCE.md").is_file()), None)


def assert_same_runs(fast: list[Run], slow: list[Run], *, note: bool = False) -> None:
    """Bit for bit: every array (NaN where NaN), every metadata key (the fallback
    note, when ``note``, only on ``fast``)."""
    assert [r.name for r in fast] == [r.name for r in slow]
    for f, s in zip(fast, slow, strict=True):
        meta = dict(f.metadata)
        assert (meta.pop(FALLBACK_KEY, None) is not None) == note
        assert meta == s.metadata
        assert f.sha256 == s.sha256 and f.source == s.source
        for a, b in [(f.time_s, s.time_s), (f.temperature_c, s.temperature_c),
                     *((f.rates_dps[k], s.rates_dps[k]) for k in "xyz")]:
            assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
        assert sorted(f.extra) == sorted(s.extra)
        for k in f.extra:
            assert np.array_equal(f.extra[k], s.extra[k], equal_nan=True)
