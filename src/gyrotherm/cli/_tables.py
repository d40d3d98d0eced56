"""Plain-text tables in the style of Tang et al.'s Table 1 and Table 2."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from gyrotherm.compensation import Calibration, RunScore


def _fmt(v: float) -> str:
    return f"{v:>13.6g}"


def coefficient_table(
    rows: Sequence[tuple[str, Calibration]],
    axis: str,
    *,
    title: str = "",
    truth: dict[str, float] | None = None,
) -> str:
    """Table 1 style: one row per fit, one column per term, physical units.

    ``truth`` adds a last row of known coefficients (term name → value).
    """
    if not rows:
        return ""
    terms = rows[0][1].model.term_names
    width = max(12, *(len(name) for name, _ in rows))
    head = f"{'fit':<{width}}" + "".join(f"{t:>13}" for t in terms)
    lines = [title or f"Coefficients, axis {axis} (bias in °/s; T, ΔT in °C)", head,
             "-" * len(head)]
    for name, cal in rows:
        phys = cal.physical_coefficients(axis)
        lines.append(f"{name:<{width}}" + "".join(_fmt(phys[t]) for t in terms))
    if truth is not None:
        lines.append(f"{'truth':<{width}}" + "".join(_fmt(truth.get(t, 0.0)) for t in terms))
    return "\n".join(lines)


def error_table(columns: Sequence[tuple[str, Sequence[RunScore]]], *, title: str = "") -> str:
    """Table 2 style: columns are models, rows the error statistics (°/s).

    Each column's scores are averaged over the axes (and runs) it holds.
    """
    stats: list[tuple[str, Callable[[RunScore], float]]] = [
        ("|average error|", lambda s: abs(s.compensated.mean_dps)),
        ("RMS error", lambda s: s.compensated.rms_dps),
        ("max |error|", lambda s: s.compensated.max_abs_dps),
        ("RMS vs true bias", lambda s: s.truth.rms_dps if s.truth else float("nan")),
    ]
    width = max(13, *(len(name) + 2 for name, _ in columns))
    head = f"{'(°/s)':<18}" + "".join(f"{name:>{width}}" for name, _ in columns)
    raw = columns[0][1]
    lines = [title, head, "-" * len(head)] if title else [head, "-" * len(head)]
    lines.append(
        f"{'raw RMS':<18}" + f"{np.mean([s.raw.rms_dps for s in raw]):>{width}.4f}"
    )
    for label, get in stats:
        vals = [float(np.mean([get(s) for s in scores])) for _, scores in columns]
        if all(np.isnan(vals)):
            continue
        lines.append(f"{label:<18}" + "".join(f"{v:>{width}.4f}" for v in vals))
    return "\n".join(lines)


def score_table(scores: Sequence[RunScore]) -> str:
    """Per run and axis: raw and compensated mean / RMS / max, °/s."""
    width = max(10, *(len(s.run) for s in scores)) if scores else 10
    head = (f"{'run':<{width}} axis {'raw mean':>10} {'raw RMS':>10} {'raw max':>10} "
            f"{'comp mean':>10} {'comp RMS':>10} {'comp max':>10} {'clamped':>8}")
    lines = [head, "-" * len(head)]
    for s in scores:
        lines.append(
            f"{s.run:<{width}} {s.axis:>4} {s.raw.mean_dps:>10.4f} {s.raw.rms_dps:>10.4f} "
            f"{s.raw.max_abs_dps:>10.4f} {s.compensated.mean_dps:>10.4f} "
            f"{s.compensated.rms_dps:>10.4f} {s.compensated.max_abs_dps:>10.4f} "
            f"{s.clamped_fraction:>7.1%}"
        )
    return "\n".join(lines)
