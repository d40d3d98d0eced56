"""PNG figures of a :class:`Diagnosis` (matplotlib, no pyplot), for :mod:`._report`.

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

Each ``figure_*`` function returns a :class:`matplotlib.figure.Figure` (no pyplot),
which the tests inspect; ``plot_*`` saves it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gyrotherm.analysis._diagnose import Diagnosis
from gyrotherm.analysis._stats import allan_deviation


def _figure(**kw: Any) -> Any:
    from matplotlib.figure import Figure  # no pyplot: no global state; Agg on savefig

    return Figure(**kw)


def _save(fig: Any, path: Path) -> None:
    fig.savefig(path, dpi=110)


def _means(x: np.ndarray, y: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    k = np.floor(x / width)
    keys, inv, counts = np.unique(k, return_inverse=True, return_counts=True)
    sums = np.bincount(inv, weights=y)
    ok = counts >= 10
    return (keys[ok] + 0.5) * width, sums[ok] / counts[ok]


#: Measured, simulated with the paper model, simulated with the extended model.
SIM_STYLES = {"measured": ("k", "-", 1.6), "paper": ("tab:blue", "--", 1.2),
              "extended": ("tab:red", ":", 1.6)}


def figure_measured_vs_simulated(d: Diagnosis) -> Any:
    """Every run: output (60-s means, offset removed) measured and simulated with the
    paper and extended models, each in its own style; below it simulated − measured,
    where the models differ visibly; below that T."""
    sim = d.simulation
    if sim is None:
        raise ValueError("the diagnosis has no simulation comparison")
    n = len(d.prepared)
    cols = min(3, n)
    blocks = -(-n // cols)
    fig = _figure(figsize=(5 * cols, 7 * blocks))
    grid = fig.add_gridspec(3 * blocks, cols, height_ratios=[2, 1.2, 1] * blocks)
    for j, p in enumerate(d.prepared):
        b, c = divmod(j, cols)
        out_ax = fig.add_subplot(grid[3 * b, c])
        diff_ax = fig.add_subplot(grid[3 * b + 1, c], sharex=out_ax)
        t_ax = fig.add_subplot(grid[3 * b + 2, c], sharex=out_ax)
        measured = p.rate_dps - d.baseline.offsets_dps[p.name]
        mx, my = _means(p.time_s, measured, 60.0)
        colour, ls, lw = SIM_STYLES["measured"]
        out_ax.plot(mx / 60, my, color=colour, ls=ls, lw=lw, label="measured", zorder=1)
        for key, preps, label in (("paper", sim.prepared, "simulated, paper model"),
                                  ("extended", sim.extended_prepared,
                                   f"simulated, extended ({d.extended.name})")):
            q = preps[j]
            y = q.rate_dps - np.mean(q.rate_dps) + np.mean(measured)
            sx, sy = _means(q.time_s, y, 60.0)
            colour, ls, lw = SIM_STYLES[key]
            out_ax.plot(sx / 60, sy, color=colour, ls=ls, lw=lw, label=label, zorder=2)
            common, i_s, i_m = np.intersect1d(sx, mx, return_indices=True)
            diff_ax.plot(common / 60, sy[i_s] - my[i_m], color=colour, ls=ls, lw=lw,
                         label=f"{label} − measured")
        diff_ax.axhline(0, color="k", lw=0.5)
        out_ax.set_title(p.name, fontsize=9)
        out_ax.set_ylabel(f"rate {d.axis}, offset removed,\n60-s means (°/s)", fontsize=8)
        diff_ax.set_ylabel("simulated − measured (°/s)", fontsize=8)
        t_ax.plot(p.time_s / 60, p.temperature_c, color="tab:orange")
        t_ax.set_xlabel("time since power-on (min)")
        t_ax.set_ylabel("T (°C)")
        if j == 0:
            out_ax.legend(fontsize=7)
            diff_ax.legend(fontsize=6)
    fig.tight_layout()
    return fig


def plot_measured_vs_simulated(d: Diagnosis, path: Path) -> None:
    _save(figure_measured_vs_simulated(d), path)


def figure_residual_vs_temperature(d: Diagnosis) -> Any:
    """Baseline residual (1-s blocks, every 5th) against T by the direction of the last
    move, with 2 °C bin means of every block."""
    fig = _figure(figsize=(7, 4.5))
    ax = fig.add_subplot()
    t = np.concatenate([p.temperature_c for p in d.prepared])
    h = np.concatenate([p.direction for p in d.prepared])
    e = np.concatenate(d.residuals)
    for sign, label, color in ((1, "heating (last move up)", "tab:red"),
                               (-1, "cooling (last move down)", "tab:blue"),
                               (0, "before the first move", "0.6")):
        m = h == sign
        if m.any():
            ax.scatter(t[m][::5], e[m][::5], s=1, color=color, alpha=0.25,
                       label=f"{label}: 1-s blocks, every 5th")
            if sign:
                bx, by = _means(t[m], e[m], 2.0)
                ax.plot(bx, by, color=color, lw=2, label=f"{label}: 2 °C bin means")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("T (°C)")
    ax.set_ylabel("baseline residual (°/s)")
    ax.set_title("Paper-model residual against temperature, heating vs cooling")
    ax.legend(fontsize=7, markerscale=6)
    fig.tight_layout()
    return fig


def plot_residual_vs_temperature(d: Diagnosis, path: Path) -> None:
    _save(figure_residual_vs_temperature(d), path)


def figure_residual_vs_time(d: Diagnosis) -> Any:
    fig = _figure(figsize=(11, 4))
    axes = fig.subplots(1, 2, sharey=True)
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
    return fig


def plot_residual_vs_time(d: Diagnosis, path: Path) -> None:
    _save(figure_residual_vs_time(d), path)


def raw_rms(d: Diagnosis) -> tuple[tuple[float, ...], float]:
    """Per run and pooled: RMS of the raw output on the 1-s blocks, each run's own mean
    removed — what the held-out RMS is with no model at all."""
    sq = [np.square(p.rate_dps - np.mean(p.rate_dps)) for p in d.prepared]
    per_run = tuple(float(np.sqrt(np.mean(v))) for v in sq)
    return per_run, float(np.sqrt(np.sum([v.sum() for v in sq]) / sum(v.size for v in sq)))


def figure_before_after(d: Diagnosis) -> Any:
    """Every run: raw, paper (baseline) and extended held-out RMS side by side (log
    scale, distinct colours and hatches); below, extended − paper per run, °/s."""
    names = [p.name for p in d.prepared]
    raw, raw_all = raw_rms(d)
    series = (("raw output, own mean removed", raw, raw_all, "0.7", "//"),
              ("paper (baseline), held out", d.heldout_baseline, d.baseline_heldout_rms_dps,
               "tab:blue", ""),
              (f"extended ({d.extended.name}), held out", d.heldout_extended,
               d.extended_heldout_rms_dps, "tab:red", ".."))
    n = len(names)
    fig = _figure(figsize=(max(6.0, 0.9 * n + 2.5), 6.5))
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    x = np.arange(n)
    width = 0.27
    for k, (label, values, pooled, colour, hatch) in enumerate(series):
        top.bar(x + (k - 1) * width, values, width, color=colour, hatch=hatch,
                edgecolor="k", linewidth=0.4, label=f"{label}: all runs {pooled:.4g}")
    top.set_yscale("log")
    low, high = min(min(v) for _, v, *_ in series), max(max(v) for _, v, *_ in series)
    top.set_ylim(low / 2, high * 12)  # room above the bars for the legend
    top.set_ylabel("RMS (°/s, 1-s blocks; log scale)")
    top.set_title(f"Leave-one-run-out, axis {d.axis}, {n} runs: gain {d.gain:.2f} "
                  "(paper ÷ extended)", fontsize=10)
    top.legend(fontsize=7)
    change = np.asarray(d.heldout_extended) - np.asarray(d.heldout_baseline)
    bottom.bar(x, change, 0.5, color=["tab:green" if v < 0 else "tab:purple" for v in change],
               edgecolor="k", linewidth=0.4)
    bottom.axhline(0, color="k", lw=0.6)
    bottom.set_ylabel("extended − paper,\nheld-out RMS (°/s)", fontsize=8)
    bottom.set_xticks(x, names, rotation=30, ha="right", fontsize=7)
    fig.tight_layout()
    return fig


def plot_before_after(d: Diagnosis, path: Path) -> None:
    _save(figure_before_after(d), path)


def figure_allan(d: Diagnosis) -> Any:
    fig = _figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    longest = max(len(p) for p in d.prepared)
    taus = np.unique(np.geomspace(1, max(2, longest // 3), 25).astype(int))
    curves = [("measured, paper residual", d.residuals, "k", "-")]
    if d.simulation is not None:
        curves.append(("simulated, paper residual", d.simulation.residuals, "tab:blue", "--"))
    curves.append(("measured, extended residual", d.extended_residuals, "tab:red", ":"))
    for label, resid, color, ls in curves:
        adev = [allan_deviation(resid, int(m)) for m in taus]
        ax.loglog(taus, adev, label=label, color=color, ls=ls)
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel("Allan deviation (°/s)")
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_allan(d: Diagnosis, path: Path) -> None:
    _save(figure_allan(d), path)


__all__ = ["SIM_STYLES", "figure_allan", "figure_before_after", "figure_measured_vs_simulated",
           "figure_residual_vs_temperature", "figure_residual_vs_time", "plot_allan",
           "plot_before_after", "plot_measured_vs_simulated", "plot_residual_vs_temperature",
           "plot_residual_vs_time", "raw_rms"]
