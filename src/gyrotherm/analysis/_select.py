"""Forward selection of effects with a backward pass (scores from :mod:`._score`).

An effect enters (greedy forward selection) only when (1) held-out RMS
improves by at least ``margin`` (relative), (2) the held-out SSE improves on at
least half of the runs, and (3) ΔBIC_eff < 0. Every step tries each remaining
effect and each pair of them (two effects can cancel so that neither helps
alone); among the candidates that pass, the best held-out RMS among the
simplest (fewest parameters) is taken unless a more complex one passes the
same criteria against it: a warm-up stretched over the whole run must not win
over a drift, nor a pair over the better of its effects, by a hair.

Nonlinear parameters: coordinate descent from single-effect fits can stall in
the wrong mode (a lag fitted alone comes out too long, and a hysteresis of
the opposite sign then compensates it). So when an effect joins a model
holding one nonlinear parameter, both are searched jointly, a pair of
candidate effects is searched jointly, and after every acceptance all
nonlinear parameters of the model are refined jointly (up to two; coordinate
descent beyond).

At the end, effects whose removal no longer costs ``margin`` are dropped
(backward pass), and a ``thermal_lag`` next to a ``hysteresis`` must also pass
with the hysteresis driven by the sensed temperature: the hysteresis follows
the lagged (structure) temperature, so a lag also delays its switch, and a
hysteresis that switches more slowly than its regressor would otherwise buy a
spurious lag.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gyrotherm.analysis._effects import EFFECTS, TAU_GRIDS
from gyrotherm.analysis._score import Evaluation, Selector


@dataclass(frozen=True)
class Step:
    """One accepted effect with the evidence for it."""

    effect: str
    before: Evaluation
    after: Evaluation
    runs_improved: int
    delta_bic: float


@dataclass(frozen=True)
class Selection:
    baseline: Evaluation
    final: Evaluation
    steps: tuple[Step, ...]
    alone: Mapping[str, Evaluation]
    tried: Mapping[str, tuple[float, int, float]]
    """Per effect tried on the baseline: (held-out ratio, runs improved, ΔBIC)."""


def _compare(before: Evaluation, after: Evaluation) -> tuple[float, int, float]:
    ratio = before.heldout_rms_dps / after.heldout_rms_dps
    improved = int(np.sum(after.heldout_sse < before.heldout_sse))
    n_eff = min(before.n_eff, after.n_eff)
    delta_bic = after.bic(n_eff) - before.bic(n_eff)
    return ratio, improved, delta_bic


def enters(before: Evaluation, after: Evaluation, *, margin: float, n_runs: int) -> bool:
    """The entry criteria: ``after`` over ``before`` held out by ×(1 + ``margin``), better on
    at least half of the ``n_runs`` left-out runs, and ΔBIC_eff < 0."""
    ratio, improved, dbic = _compare(before, after)
    return ratio >= 1.0 + margin and improved >= math.ceil(n_runs / 2) and dbic < 0.0


def select(
    selector: Selector,
    *,
    margin: float = 0.10,
    candidates: Sequence[str] = EFFECTS,
    pairs: bool = True,
    progress: Callable[[str], None] | None = None,
) -> Selection:
    """Greedy forward selection with a backward pass (see the module docstring).

    With ``pairs``, every step also tries each pair of remaining effects: two
    effects can cancel each other (a lag and a hysteresis of opposite signs) so
    that neither helps alone. Among the candidates that pass against the
    current model, :func:`_simplest_best` picks the one to accept.
    """
    say = progress or (lambda _msg: None)

    def passes(before: Evaluation, after: Evaluation) -> bool:
        return enters(before, after, margin=margin, n_runs=len(selector.runs))

    baseline = selector.evaluate({})
    current = baseline
    steps: list[Step] = []
    alone: dict[str, Evaluation] = {}
    tried: dict[str, tuple[float, int, float]] = {}
    while True:
        singles: dict[str, Evaluation] = {}
        for name in candidates:
            if name in current.effects:
                continue
            trial = selector.evaluate({**current.effects, name: 0.0},
                                      search=_joint(current.effects, name))
            singles[name] = trial
            if not current.effects:
                alone[name] = trial
                tried[name] = _compare(baseline, trial)
                say(f"{name}: held-out gain {tried[name][0]:.3f}, runs improved "
                    f"{tried[name][1]}/{len(selector.runs)}, ΔBIC_eff {tried[name][2]:.1f}")
        passing: list[tuple[tuple[str, ...], Evaluation]] = [
            ((n,), ev) for n, ev in singles.items() if passes(current, ev)]
        if pairs:
            names = sorted(singles, key=EFFECTS.index)
            for i, a in enumerate(names):
                for b in names[i + 1:]:
                    trial = _pair(selector, current, singles, a, b)
                    if passes(current, trial):
                        passing.append(((a, b), trial))
        if not passing:
            break
        added, best = _simplest_best(passing, passes)
        ratio, improved, dbic = _compare(current, best)
        refined = _refine_all(selector, best)
        for name in added:
            steps.append(Step(name, current, refined, improved, dbic))
        say(f"accepted {' + '.join(added)}{' together' if len(added) > 1 else ''} "
            f"(held-out gain {ratio:.3f})")
        current = refined
    # backward pass: drop effects that no longer earn their place
    current, dropped = prune(selector, current, margin=margin)
    for name in dropped:
        say(f"dropped {name} (redundant given the others)")
    steps = [s for s in steps if s.effect not in dropped]
    if _lag_only_times_hysteresis(selector, current, passes):
        say("dropped thermal_lag (with the hysteresis on the sensed temperature it buys "
            "nothing: it only delayed the hysteresis)")
        rest = {k: v for k, v in current.effects.items() if k != "thermal_lag"}
        current = _refine_all(selector, selector.evaluate(rest))
        steps = [s for s in steps if s.effect != "thermal_lag"]
    for name in current.effects:
        if name not in alone:
            alone[name] = selector.evaluate({name: 0.0}, search=name)
    return Selection(baseline, current, tuple(steps), alone, tried)


def prune(selector: Selector, current: Evaluation, *, margin: float = 0.10
          ) -> tuple[Evaluation, tuple[str, ...]]:
    """The backward pass of :func:`select` on ``current``: drop, one at a time, the effects
    that no longer earn their place (the entry criteria against the model without them),
    e.g. once an effect they were selected with was left out as not resolvable; the
    model that remains and what was dropped."""
    dropped: list[str] = []
    changed = True
    while changed and current.effects:
        changed = False
        for name in list(current.effects):
            rest = {k: v for k, v in current.effects.items() if k != name}
            without = _refine_all(selector, selector.evaluate(rest))
            if not enters(without, current, margin=margin, n_runs=len(selector.runs)):
                current = without
                dropped.append(name)
                changed = True
                break
    return current, tuple(dropped)


def _simplest_best(
    passing: Sequence[tuple[tuple[str, ...], Evaluation]],
    passes: Callable[[Evaluation, Evaluation], bool],
) -> tuple[tuple[str, ...], Evaluation]:
    """The candidate to accept: the best held-out RMS among the simplest (fewest
    parameters, then fewest effects), replaced by a more complex one only when
    that one passes the entry criteria against it. A long warm-up passes for a
    drift, a pair contains the better of its singles: the extra parameter has
    to earn its place like an effect does."""
    order = sorted(passing, key=lambda c: (c[1].k, len(c[0]), c[1].heldout_rms_dps))
    best = order[0]
    for cand in order[1:]:
        simpler = (cand[1].k, len(cand[0])) == (best[1].k, len(best[0]))
        if (cand[1].heldout_rms_dps < best[1].heldout_rms_dps) if simpler \
                else passes(best[1], cand[1]):
            best = cand
    return best


def _pair(
    selector: Selector, current: Evaluation, singles: Mapping[str, Evaluation], a: str, b: str
) -> Evaluation:
    """``current`` + effects a and b; their time constants are searched jointly."""
    effects = {**current.effects, a: singles[a].effects[a], b: singles[b].effects[b]}
    return selector.evaluate(effects, search=[e for e in (a, b) if e in TAU_GRIDS])


def _joint(effects: Mapping[str, float], name: str) -> list[str]:
    """What to search when ``name`` joins ``effects``: its nonlinear parameter, jointly
    with the one already in the model when there is exactly one (a lag found
    first, at the wrong time constant, must be free to move when a hysteresis
    joins it; a warm-up stretched to mimic a drift must shrink back when the
    drift joins). With two or more already in the model, only its own."""
    own = [name] if name in TAU_GRIDS else []
    present = [e for e in effects if e in TAU_GRIDS and e != name]
    return [*own, *present] if len(present) == 1 else own


def _lag_only_times_hysteresis(
    selector: Selector, current: Evaluation, passes: Callable[[Evaluation, Evaluation], bool]
) -> bool:
    """Whether the model's ``thermal_lag`` earns its place only through the hysteresis.

    The hysteresis follows the lagged (structure) temperature, so a lag also
    delays the hysteresis switch; a hysteresis whose switch is slower than its
    regressor's can then buy a spurious lag. A real lag also acts on the
    temperature terms: with the hysteresis driven by the sensed temperature,
    the lag must still pass the entry criteria against the model without it.
    """
    if not {"thermal_lag", "hysteresis"} <= set(current.effects):
        return False
    plain = Selector(selector.runs, selector.scaling, hysteresis_follows_lag=False)
    rest = {k: v for k, v in current.effects.items() if k != "thermal_lag"}
    without = _refine_all(plain, plain.evaluate(rest))
    decoupled = _refine_all(plain, plain.evaluate(dict(current.effects)))
    return not passes(without, decoupled)


def _refine_all(selector: Selector, ev: Evaluation, rounds: int = 2) -> Evaluation:
    """Joint refinement of the nonlinear parameters of the model's effects: a joint grid
    and Nelder–Mead for up to two, else coordinate descent."""
    nonlinear = [e for e in ev.effects if e in TAU_GRIDS]
    if not nonlinear:
        return ev
    if len(nonlinear) <= 2:
        return selector.evaluate(dict(ev.effects), search=nonlinear)
    current = ev
    for _ in range(rounds):
        for name in nonlinear:
            current = selector.evaluate(dict(current.effects), search=name)
    return current
