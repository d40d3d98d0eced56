"""Markdown report with PNG plots for a :class:`Diagnosis` (matplotlib, Agg backend).

Files written to the report directory:

* ``report.md``;
* ``measured_vs_simulated.png``: 1-s output of up to three runs, measured,
  simulated with the baseline and with the extended model;
* ``residual_vs_temperature.png``: baseline residual against T, heating and
  cooling (direction of the last move) apart, with 2 °C bin means;
* ``residual_vs_time.png``: baseline and extended residuals against time
  since power-on (60-s means);
* ``before_after.png``: held-out RMS per left-out run, baseline vs extended;
* ``allan.png``: Allan deviation of the residuals, measured vs simulated.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.analysis._compare import SimulationComparison
from gyrotherm.analysis._diagnose import Diagnosis
from gyrotherm.analysis._stats import allan_deviation


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _means(x: np.ndarray, y: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    k = np.floor(x / width)
    keys, inv, counts = np.unique(k, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, weights=y)
    ok = counts >= 10
    return (keys[ok] + 0.5) * width, sums[ok] / counts[ok]


def plot_measured_vs_simulated(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    sim = d.simulation
    n = min(3, len(d.prepared))
    fig, axes = plt.subplots(2, n, figsize=(5 * n, 6), squeeze=False, sharex="col")
    for j in range(n):
        p = d.prepared[j]
        ax = axes[0][j]
        ax.plot(p.time_s / 60, p.rate_dps - d.baseline.offsets_dps[p.name], lw=0.5,
                label="measured", color="k")
        if sim is not None:
            for preps, label, color in ((sim.prepared, "simulated (paper)", "tab:blue"),
                                        (sim.extended_prepared, "simulated (extended)",
                                         "tab:red")):
                q = preps[j]
                ax.plot(q.time_s / 60, q.rate_dps - np.mean(q.rate_dps) + np.mean(
                    p.rate_dps - d.baseline.offsets_dps[p.name]), lw=0.5, label=label,
                    color=color, alpha=0.8)
        ax.set_title(p.name, fontsize=9)
        ax.set_ylabel(f"rate {d.axis}, offset removed (°/s)")
        axes[1][j].plot(p.time_s / 60, p.temperature_c, color="tab:orange")
        axes[1][j].set_xlabel("time since power-on (min)")
        axes[1][j].set_ylabel("T (°C)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_residual_vs_temperature(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    t = np.concatenate([p.temperature_c for p in d.prepared])
    h = np.concatenate([p.direction for p in d.prepared])
    e = np.concatenate(d.residuals)
    for sign, label, color in ((1, "heating (last move up)", "tab:red"),
                               (-1, "cooling (last move down)", "tab:blue"),
                               (0, "before the first move", "0.6")):
        m = h == sign
        if m.any():
            ax.scatter(t[m][::5], e[m][::5], s=1, color=color, alpha=0.25)
            if sign:
                bx, by = _means(t[m], e[m], 2.0)
                ax.plot(bx, by, color=color, lw=2, label=label)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("T (°C)")
    ax.set_ylabel("baseline residual (°/s)")
    ax.set_title("Paper-model residual against temperature, heating vs cooling")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_residual_vs_time(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, resid, title in ((axes[0], d.residuals, "baseline (paper)"),
                             (axes[1], d.extended_residuals, f"extended ({d.extended.name})")):
        for p, e in zip(d.prepared, resid, strict=True):
            bx, by = _means(p.time_s, e, 60.0)
            ax.plot(bx / 60, by, lw=1, label=p.name)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time since power-on (min)")
    axes[0].set_ylabel("residual, 60-s means (°/s)")
    axes[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_before_after(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(max(5, 1.1 * len(d.prepared)), 4))
    x = np.arange(len(d.prepared))
    ax.bar(x - 0.2, d.heldout_baseline, 0.4, label=f"paper: {d.baseline_heldout_rms_dps:.4g}")
    ax.bar(x + 0.2, d.heldout_extended, 0.4,
           label=f"{d.extended.name}: {d.extended_heldout_rms_dps:.4g}")
    ax.set_xticks(x, [p.name for p in d.prepared], rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("held-out RMS (°/s, 1-s blocks)")
    ax.set_title(f"Leave-one-run-out, gain {d.gain:.2f}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_allan(d: Diagnosis, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    longest = max(len(p) for p in d.prepared)
    taus = np.unique(np.geomspace(1, max(2, longest // 3), 25).astype(int))
    curves = [("measured, paper residual", d.residuals, "k")]
    if d.simulation is not None:
        curves.append(("simulated, paper residual", d.simulation.residuals, "tab:blue"))
    curves.append(("measured, extended residual", d.extended_residuals, "tab:red"))
    for label, resid, color in curves:
        adev = [allan_deviation(resid, int(m)) for m in taus]
        ax.loglog(taus, adev, label=label, color=color)
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel("Allan deviation (°/s)")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
                  "not deployable (kept out of the extended model and of --calibration)",
                  f"- held-out RMS with the correction: {_fmt(u.heldout_rms_dps)} °/s "
                  f"(gain {u.gain:.3f})", f"- evidence: {u.evidence}", ""]
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
