"""Markdown report with PNG plots for a :class:`Diagnosis` (matplotlib, Agg backend).

Files written to the report directory:

* ``report.md``;
* ``measured_vs_simulated.png``: every run's output (60-s means), measured and
  simulated with the baseline and with the extended model in distinct styles, the
  simulated − measured differences below, T at the bottom;
* ``residual_vs_temperature.png``: baseline residual against T, heating and
  cooling (direction of the last move) apart, with 2 °C bin means;
* ``residual_vs_time.png``: baseline and extended residuals against time
  since power-on (60-s means);
* ``before_after.png``: per run (every run), the raw output's RMS, the baseline's and
  the extended model's held-out RMS side by side (log scale), and below the change
  extended − baseline (°/s);
* ``allan.png``: Allan deviation of the residuals, measured vs simulated.

The figures are drawn by :mod:`._figures`.
"""

from __future__ import annotations

import math
from pathlib import Path

from gyrotherm.analysis._compare import SimulationComparison
from gyrotherm.analysis._diagnose import Diagnosis
from gyrotherm.analysis._figures import (
    plot_allan,
    plot_before_after,
    plot_measured_vs_simulated,
    plot_residual_vs_temperature,
    plot_residual_vs_time,
    raw_rms,
)
from gyrotherm.analysis._unexplained import Unexplained


def _fmt(v: float | None) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def _pm(mean: float | None, std: float | None) -> str:
    if mean is None or std is None:
        return "—"
    return f"{_fmt(mean)} ± {_fmt(std)}"


def _z(z: float | None, significant: bool | None) -> str:
    if z is None or not math.isfinite(z):
        return "—"
    return f"**{z:+.1f}**" if significant else f"{z:+.1f}"


def _where_line(u: Unexplained) -> str:
    """Where the structure is, against the data's range: outside ``where`` the correction
    does not change by 3 standard errors (:mod:`._where`), which is no claim that the
    structure is absent there."""
    lo, hi, k0, k1 = u.where[0], u.where[1], u.knots[0], u.knots[-1]
    text = (f"- where it changes: [{lo:.4g}, {hi:.4g}] of the data's [{k0:.4g}, {k1:.4g}] "
            f"{u.variable}")
    if (lo, hi) == (k0, k1):
        return text + " (all of it)"
    return text + ("; beyond, its change is within the noise (the data cannot place the "
                   "structure there, nor rule it out)")


def _simulation_section(sim: SimulationComparison, extended_name: str | None) -> list[str]:
    """``extended_name``: the extended model's name, None when nothing was found."""
    n = sim.replays
    lines = ["", "## Simulation against measurement", "",
             f"The simulator, calibrated to these runs, replays their temperature histories "
             f"{n} times (different noise seeds); the paper model is refitted to each "
             "replay as to the measured runs. For each statistic of the paper-model "
             "residual: the measured value, the replays' mean ± standard deviation, and "
             "z = (measured − mean)/std. **Bold** z: significant, |z| > "
             f"{sim.z_threshold:.2f} — outside the 99.73 % prediction interval of one more "
             f"replay (Student t with {n - 1} degrees of freedom, × √(1 + 1/{n})), so that a "
             "right simulator marks a given statistic with probability 0.0027. Largest |z| "
             "first."]
    if extended_name is not None:
        lines[-1] += (f" The extended columns replay the extended model ({extended_name}) "
                      "with the same noise: does modelling the effects close the gap?")
    sig = [m.statistic for m in sim.significant]
    lines += ["", "Significant mismatches (paper model): "
              + (", ".join(sig) if sig else "none") + "."]
    header = "| statistic | measured | simulated (paper), mean ± std | z |"
    rule = "|---|---|---|---|"
    if extended_name is not None:
        still = [m.statistic for m in sim.mismatch if m.extended_significant]
        lines.append("Still significant with the extended model: "
                     + (", ".join(still) if still else "none") + ".")
        header += " simulated (extended), mean ± std | z (extended) |"
        rule += "---|---|"
    lines += ["", header, rule]
    for m in sim.mismatch:
        row = (f"| {m.statistic} | {_fmt(m.measured)} | {_pm(m.sim_mean, m.sim_std)} | "
               f"{_z(m.z, m.significant)} |")
        if extended_name is not None:
            row += (f" {_pm(m.extended_mean, m.extended_std)} | "
                    f"{_z(m.extended_z, m.extended_significant)} |")
        lines.append(row)
    if sim.omitted:
        lines += ["", "Left out (see Notes): " + ", ".join(name for name, _ in sim.omitted)
                  + "."]
    lines += ["", "Simulator calibration: " + ", ".join(
        f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"
        for k, v in sim.calibration.to_dict().items())]
    return lines


def write_report(d: Diagnosis, directory: str | Path) -> Path:
    """Write ``report.md`` and the plots into ``directory``; return the Markdown path."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    plot_residual_vs_temperature(d, out / "residual_vs_temperature.png")
    plot_residual_vs_time(d, out / "residual_vs_time.png")
    plot_before_after(d, out / "before_after.png")
    plot_allan(d, out / "allan.png")
    figures = ["residual_vs_temperature.png", "residual_vs_time.png", "before_after.png",
               "allan.png"]
    if d.simulation is not None:
        plot_measured_vs_simulated(d, out / "measured_vs_simulated.png")
        figures.insert(0, "measured_vs_simulated.png")
    lines = [
        f"# Diagnosis: axis {d.axis}, {len(d.prepared)} runs",
        "",
        "Runs: " + ", ".join(p.name for p in d.prepared),
        "",
        "| model | held-out RMS (°/s) | gain |",
        "|---|---|---|",
        f"| raw output, each run's mean removed (no model) | {_fmt(raw_rms(d)[1])} | — |",
        f"| paper (baseline) | {_fmt(d.baseline_heldout_rms_dps)} | 1 |",
        f"| {d.extended.name} | {_fmt(d.extended_heldout_rms_dps)} | {d.gain:.3f} |",
        "",
        "Held-out RMS: leave-one-run-out on 1-s blocks, each left-out run's own mean "
        "residual (switch-on offset) removed.",
        "",
        "## Findings",
        "",
    ]
    if not d.findings and not d.unexplained:
        lines.append("No candidate effect improved left-out runs by the required margin: "
                     "nothing found.")
    for f in d.findings:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in f.params.items())
        lines += [f"### {f.effect}", "", f"- parameters: {params}",
                  f"- held-out RMS with this effect alone: {_fmt(f.heldout_rms_dps)} °/s "
                  f"(gain {f.gain:.3f})", f"- evidence: {f.evidence}", ""]
    for u in d.unexplained:
        lines += [f"### unexplained: {u.variable} in [{u.where[0]:.4g}, {u.where[1]:.4g}]", "",
                  "- structure no catalogued effect explains; its linear-spline correction is "
                  "deployed by --calibration as the axis' `correction` (the first such "
                  "structure; refitted on the vehicle's estimator features)",
                  f"- held-out RMS with the correction: {_fmt(u.heldout_rms_dps)} °/s "
                  f"(gain {u.gain:.3f})", _where_line(u), f"- evidence: {u.evidence}", ""]
    for v in d.not_resolvable:
        lines += ["", f"## {v.effect}: not resolvable at this readout", "",
                  f"- fitted: {', '.join(f'{k} = {_fmt(x)}' for k, x in v.params.items())}",
                  f"- reason: {v.reason}"]
    if d.floors:
        lines += ["", "## Detection floor", "",
                  "A structure in a variable gaining less than its floor held out over the "
                  f"{d.extended.name} model is not resolvable at this readout, whatever its "
                  "shape: the floor is the margin above what readout replays without any "
                  "structure give a spline in it.", "",
                  "| variable | floor (held-out gain) | about (°/s RMS) | replays without one |",
                  "|---|---|---|---|"]
        lines += [f"| {f.variable} | ×{f.gain:.3f} | {_fmt(f.rms_dps)} | ×{f.null_gain:.3f} |"
                  for f in d.floors]
    lines += ["", "## Effects tried on the baseline", "",
              "| effect | held-out gain | left-out runs improved | ΔBIC_eff |", "|---|---|---|---|"]
    for name, (ratio, improved, dbic) in d.selection.tried.items():
        lines.append(f"| {name} | {ratio:.3f} | {improved}/{len(d.prepared)} | {dbic:.1f} |")
    if d.simulation is not None:
        lines += _simulation_section(d.simulation,
                                     d.extended.name if d.extended.effects else None)
    if d.notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in d.notes]
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    md = out / "report.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md
