"""Which catalogued effect a finding is: is it told apart from the others?

Runs that repeat one temperature profile move T, ΔT and time since power-on together, so
two catalogued effects of different physics can buy nearly the same held out: a hysteresis
whose branches are heating (at low T) and cooling (at high T) looks like a function of T
to a cubic, and a cubic is a function of T alone. The unexplained search says so for its
structures (``Unexplained.not_told_from``, :mod:`._unexplained`); this says it for the
catalogued findings, on the basis their reported gain is on (:class:`~._diagnose.Finding`:
the paper model plus that effect alone).

A catalogued effect *e* not in the final model is a rival of the finding *f* when, alone on
the paper model, it passes the selection's entry criteria (held-out ratio ≥ 1 + margin,
better on at least half of the left-out runs, ΔBIC_eff < 0) and *f* alone does not beat it
by ×(1 + margin) held out:

    RMS(paper + e) < (1 + margin) · RMS(paper + f)

Then which of the two the structure is cannot be told from these runs, and the finding
says so (``Finding.not_told_from``: rival → its held-out gain alone). Effects a verdict
left out as not resolvable (:mod:`._resolve`, :mod:`._separable`) are not rivals: the data
cannot support them. An empty listing says no other effect does as well alone, not that
the runs tell the effects apart in every combination.

It changes no finding and no model: it is a statement beside the name (round 12 of issue
19: a rate-dependent hysteresis named a cubic ×1.35 at the 1 °C corner, hysteresis alone
×1.23, with nothing said).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

from gyrotherm.analysis._score import Evaluation


def catalogued_rivals(
    baseline: Evaluation, alone: Mapping[str, Evaluation], found: Collection[str],
    excluded: Collection[str], *, n_runs: int, margin: float = 0.10,
) -> dict[str, dict[str, float]]:
    """For each effect of ``found``: the effects of ``alone`` (each alone on ``baseline``)
    that are neither found nor ``excluded``, pass the entry criteria and are not beaten by
    it by ×(1 + ``margin``) held out (module docstring), with their held-out gain alone."""
    from gyrotherm.analysis._select import enters

    candidates = {name: ev for name, ev in alone.items()
                  if name not in found and name not in excluded
                  and enters(baseline, ev, margin=margin, n_runs=n_runs)}
    out: dict[str, dict[str, float]] = {}
    for name in found:
        if name not in alone:
            continue
        rms = alone[name].heldout_rms_dps
        out[name] = {e: baseline.heldout_rms_dps / ev.heldout_rms_dps
                     for e, ev in candidates.items()
                     if ev.heldout_rms_dps < (1.0 + margin) * rms}
    return out


def listing(rivals: Mapping[str, float], *, each: str, what: str, said: str) -> str:
    """An evidence clause "; not told apart from {what}{name} (×gain {each}), …: {said}"
    ("" when ``rivals`` is empty): the form both kinds of rival are stated in."""
    if not rivals:
        return ""
    alts = ", ".join(f"{name} (×{g:.3f} {each})" for name, g in sorted(rivals.items()))
    return f"; not told apart from {what}{alts}: {said}"


def rival_text(rivals: Mapping[str, float]) -> str:
    """The evidence's clause for a finding's rivals ("" when none)."""
    return listing(rivals, each="alone held out", what="",
                   said="which of them it is is not resolvable at this readout (the runs "
                        "move T, ΔT and time together)")
