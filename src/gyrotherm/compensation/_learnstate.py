"""Learning state that streams and survives: a warm-up accumulated row by row, and the
statistics of past power-ons as a bounded, validated document.

:class:`WarmupAccumulator` is what a process fed one estimator output at a time keeps for
the current power-on (the daemon's ``[learn]`` mode; ``gyrotherm learn`` uses the batch
:meth:`WarmupStats.from_features`, equal to it to rounding: ``tests/compensation/
test_learnstate.py``): the same rows (:func:`~._learn.warmup_rows`: from ``SETTLE_S``
to ``WARMUP_MAX_S`` after power-on, at rest, until the first row in motion) and the same
sums, O(1) per row, a fixed number of floats whatever the warm-up's length.

:class:`LearnState` holds at most :data:`MAX_POWER_ONS` warm-ups (the oldest dropped
first: memory stays bounded) and reads back only what it could have written: every
number finite, every list of its length, counts non-negative, at most
:data:`MAX_POWER_ONS` entries; anything else is a :class:`CalibrationError` naming the
field, so a corrupt or foreign file is refused whole and nothing in it is learnt.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation._learn import (
    MIN_ROWS,
    SETTLE_S,
    WARMUP_MAX_S,
    K,
    WarmupStats,
    _z,
)

MAX_POWER_ONS = 256
#: 2: six basis terms per warm-up (the paper model's four, then x³ and g² for the effects);
#: version 1 kept four and cannot be extended (its rows are gone): it is refused, saying so.
STATE_VERSION = 2


class WarmupAccumulator:
    """The running sums of one power-on's warm-up (module docstring)."""

    def __init__(self, name: str, axes: Sequence[str]) -> None:
        self.name = name
        self.axes = tuple(axes)
        self.n = 0
        self.closed = False  # motion seen or WARMUP_MAX_S passed: nothing more is added
        self._sz = np.zeros(K)
        self._szz = np.zeros((K, K))
        self._sy = dict.fromkeys(self.axes, 0.0)
        self._szy = {a: np.zeros(K) for a in self.axes}
        self._syy = dict.fromkeys(self.axes, 0.0)
        self._sdd = dict.fromkeys(self.axes, 0.0)
        self._ndd = 0
        self._last: tuple[float, ...] | None = None
        self._t: list[float] = [math.inf, -math.inf]
        self._d: list[float] = [math.inf, -math.inf]
        self._start_c = math.nan

    def add(self, t_on_s: float, temperature_c: float, delta_t_c: float,
            rates_dps: Sequence[float], *, at_rest: bool) -> bool:
        """One row (time since power-on, the estimator's T̂ and ΔT̂, the axes' raw rates);
        True when it was used. The first row not at rest closes the warm-up."""
        if self.closed:
            return False
        if not at_rest or t_on_s > WARMUP_MAX_S:
            self.closed = True
            return False
        if not (t_on_s >= SETTLE_S and math.isfinite(temperature_c)
                and math.isfinite(delta_t_c) and all(math.isfinite(r) for r in rates_dps)):
            self._last = None  # a gap: the next row is not a successive one
            return False
        z = _z(np.array([temperature_c]), np.array([delta_t_c]))[0]
        self._sz += z
        self._szz += np.outer(z, z)
        for a, y in zip(self.axes, rates_dps, strict=True):
            self._sy[a] += y
            self._szy[a] += z * y
            self._syy[a] += y * y
        if self._last is not None:
            for a, y, prev in zip(self.axes, rates_dps, self._last, strict=True):
                self._sdd[a] += (y - prev) ** 2
            self._ndd += 1
        self._last = tuple(rates_dps)
        if self.n == 0:
            self._start_c = temperature_c
        self.n += 1
        self._t = [min(self._t[0], temperature_c), max(self._t[1], temperature_c)]
        self._d = [min(self._d[0], delta_t_c), max(self._d[1], delta_t_c)]
        return True

    def stats(self) -> WarmupStats | None:
        """The warm-up's :class:`WarmupStats`, or None with fewer than MIN_ROWS rows."""
        if self.n < MIN_ROWS:
            return None
        return WarmupStats(
            name=self.name, n=self.n, start_c=self._start_c,
            t_range_c=(self._t[0], self._t[1]), dt_range_c=(self._d[0], self._d[1]),
            sz=tuple(self._sz.tolist()), szz=tuple(self._szz.ravel().tolist()),
            sy=dict(self._sy), szy={a: tuple(v.tolist()) for a, v in self._szy.items()},
            syy=dict(self._syy), sdd=dict(self._sdd), ndd=self._ndd)


@dataclass
class LearnState:
    """The warm-ups learnt so far (oldest first, at most MAX_POWER_ONS)."""

    axes: tuple[str, ...]
    warmups: list[WarmupStats] = field(default_factory=list)

    def add(self, stats: WarmupStats) -> None:
        self.warmups.append(stats)
        del self.warmups[:-MAX_POWER_ONS]

    def to_dict(self) -> dict[str, Any]:
        return {"version": STATE_VERSION, "axes": list(self.axes),
                "warmups": [w.to_dict() for w in self.warmups]}

    @classmethod
    def from_dict(cls, doc: Any, *, source: str = "<memory>") -> LearnState:
        """Validated (module docstring); CalibrationError naming ``source`` and the field."""
        def bad(path: str, why: str) -> CalibrationError:
            return CalibrationError(f"{source}: field {path!r}: {why}")

        if isinstance(doc, dict) and doc.get("version") == 1:
            raise bad("version", "learning state version 1 keeps 4 basis terms per warm-up, "
                      f"version {STATE_VERSION} keeps {K} (effects are learnt too); the rows "
                      "behind it are gone, so its warm-ups cannot be used: learning starts "
                      "again (an adopted calibration is kept)")
        if not isinstance(doc, dict) or doc.get("version") != STATE_VERSION:
            raise bad("version", f"expected learning state version {STATE_VERSION}, got "
                      f"{(doc.get('version') if isinstance(doc, dict) else doc)!r:.40}")
        axes = doc.get("axes")
        if not (isinstance(axes, list) and axes and len(axes) <= 3
                and all(a in ("x", "y", "z") for a in axes) and len(set(axes)) == len(axes)):
            raise bad("axes", f"expected distinct axes among x, y, z, got {axes!r:.60}")
        items = doc.get("warmups")
        if not isinstance(items, list) or len(items) > MAX_POWER_ONS:
            raise bad("warmups", f"expected a list of at most {MAX_POWER_ONS}, got "
                      f"{type(items).__name__} of {len(items) if isinstance(items, list) else '?'}")
        state = cls(tuple(axes))
        for i, item in enumerate(items):
            state.warmups.append(_stats_from(item, tuple(axes), f"warmups[{i}]", bad))
        return state


def _num(node: Any, path: str, bad: Any) -> float:
    if isinstance(node, bool) or not isinstance(node, int | float):
        raise bad(path, f"expected a number, got {node!r:.40}")
    try:
        v = float(node)
    except OverflowError:
        raise bad(path, "number too large") from None
    if not math.isfinite(v):
        raise bad(path, f"not a finite number ({v!r})")
    return v


def _nums(node: Any, n: int, path: str, bad: Any) -> tuple[float, ...]:
    if not isinstance(node, list) or len(node) != n:
        raise bad(path, f"expected a list of {n} numbers, got {node!r:.60}")
    return tuple(_num(v, f"{path}[{j}]", bad) for j, v in enumerate(node))


def _count(node: Any, path: str, bad: Any) -> int:
    if isinstance(node, bool) or not isinstance(node, int) or not 0 <= node <= 10**12:
        raise bad(path, f"expected a count 0 … 1e12, got {node!r:.40}")
    return int(node)


def _per_axis(node: Any, axes: tuple[str, ...], path: str, bad: Any) -> Mapping[str, Any]:
    if not isinstance(node, dict) or set(node) != set(axes):
        raise bad(path, f"expected the axes {list(axes)}, got {node!r:.60}")
    return node


def _stats_from(item: Any, axes: tuple[str, ...], at: str, bad: Any) -> WarmupStats:
    if not isinstance(item, dict):
        raise bad(at, f"expected an object, got {item!r:.40}")
    name = item.get("name")
    if not isinstance(name, str) or len(name) > 256:
        raise bad(f"{at}.name", f"expected text of at most 256 characters, got {name!r:.40}")
    n = _count(item.get("n"), f"{at}.n", bad)
    if n < MIN_ROWS:
        raise bad(f"{at}.n", f"{n} rows, fewer than the {MIN_ROWS} a warm-up needs")
    sy = _per_axis(item.get("sy"), axes, f"{at}.sy", bad)
    szy = _per_axis(item.get("szy"), axes, f"{at}.szy", bad)
    syy = _per_axis(item.get("syy"), axes, f"{at}.syy", bad)
    sdd = _per_axis(item.get("sdd"), axes, f"{at}.sdd", bad)
    t_range = _nums(item.get("t_range_c"), 2, f"{at}.t_range_c", bad)
    d_range = _nums(item.get("dt_range_c"), 2, f"{at}.dt_range_c", bad)
    return WarmupStats(
        name=name, n=n, start_c=_num(item.get("start_c"), f"{at}.start_c", bad),
        t_range_c=(t_range[0], t_range[1]), dt_range_c=(d_range[0], d_range[1]),
        sz=_nums(item.get("sz"), K, f"{at}.sz", bad),
        szz=_nums(item.get("szz"), K * K, f"{at}.szz", bad),
        sy={a: _num(sy[a], f"{at}.sy.{a}", bad) for a in axes},
        szy={a: _nums(szy[a], K, f"{at}.szy.{a}", bad) for a in axes},
        syy={a: _num(syy[a], f"{at}.syy.{a}", bad) for a in axes},
        sdd={a: _num(sdd[a], f"{at}.sdd.{a}", bad) for a in axes},
        ndd=_count(item.get("ndd"), f"{at}.ndd", bad))


__all__ = ["MAX_POWER_ONS", "LearnState", "WarmupAccumulator"]
