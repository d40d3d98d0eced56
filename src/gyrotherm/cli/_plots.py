"""``fit --report DIR`` and ``evaluate --report DIR``: the figures people look at.

Per axis (``<axis>`` is x, y or z):

* ``bias_vs_temperature_<axis>.png``: the measured output (10-s means; the gyro is at
  rest, so output = bias + noise) against T, heating and cooling coloured apart, with
  the fitted model evaluated along the data (at each sample's T *and* ΔT, so a T/ΔT
  model draws one path per run, not one curve) and, dashed, the model at ΔT = 0;
* ``rate_vs_time_<axis>.png``: per run, raw and compensated output against time, with
  the temperature on a second y-axis;
* ``residual_histogram_<axis>.png``: raw and compensated output, all runs pooled, RMS
  in the legend;

and ``report.md``, an index with each run's raw and compensated RMS.

Each ``figure_*`` function returns a :class:`matplotlib.figure.Figure` (no pyplot
state) for the tests to inspect; :func:`write_fit_report` saves them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm.compensation import (
    Calibration,
    RemovedBias,
    RunFeatures,
    ZeroConfig,
    removed_bias,
    score,
)

FloatArray = NDArray[np.float64]
BLOCK_S = 10.0  # means over 10-s blocks: the bias, not the white noise, is what is drawn
STEADY_DT_C = 0.05  # |ΔT| below this, °C: neither heating nor cooling
COLOURS = {"heating": "tab:red", "cooling": "tab:blue", "steady": "0.55"}
_RULE = {"heating": f"ΔT ≥ {STEADY_DT_C:g}", "cooling": f"ΔT ≤ −{STEADY_DT_C:g}",
         "steady": f"|ΔT| < {STEADY_DT_C:g}"}


def _figure(**kw: Any) -> Any:
    from matplotlib.figure import Figure  # no pyplot: no global state, any thread

    return Figure(**kw)


def block_means(time_s: FloatArray, *series: FloatArray, block_s: float = BLOCK_S
                ) -> list[FloatArray]:
    """Means of ``time_s`` and each series over consecutive ``block_s`` blocks."""
    k = np.floor((time_s - time_s[0]) / block_s).astype(np.int64)
    _, inv, counts = np.unique(k, return_inverse=True, return_counts=True)
    return [np.bincount(inv, weights=np.asarray(s, dtype=np.float64)) / counts
            for s in (time_s, *series)]


def direction(delta_t_c: FloatArray) -> NDArray[np.str_]:
    """``heating`` / ``cooling`` / ``steady`` from the estimated ΔT (= τ·dT/dt)."""
    out = np.full(delta_t_c.shape, "steady", dtype="<U7")
    out[delta_t_c >= STEADY_DT_C] = "heating"
    out[delta_t_c <= -STEADY_DT_C] = "cooling"
    return out


Removed = Sequence[RemovedBias]
"""Per run (parallel to ``feats``), the bias removed: :func:`removed_bias`, computed once
per report (with the boot-time zero for ``evaluate --zero``)."""


def _runs(cal: Calibration, feats: Sequence[RunFeatures], axis: str,
          removed: Removed | None) -> list[tuple[RunFeatures, FloatArray]]:
    """The runs with ``axis``, each with the bias removed on that axis (°/s per row)."""
    rbs = removed if removed is not None else [removed_bias(cal, f) for f in feats]
    return [(f, np.asarray(rb.bias[axis][0], dtype=np.float64))
            for f, rb in zip(feats, rbs, strict=True) if axis in f.rates_dps]


def figure_bias_vs_temperature(cal: Calibration, feats: Sequence[RunFeatures], axis: str, *,
                               removed: Removed | None = None) -> Any:
    """Measured 10-s means against T by direction; the model along the data; at ΔT = 0."""
    fig = _figure(figsize=(7.5, 5))
    ax = fig.add_subplot()
    pts: dict[str, list[FloatArray]] = {k: [] for k in COLOURS}
    for i, (f, bias) in enumerate(_runs(cal, feats, axis, removed)):
        _, t, d, y, b = block_means(f.time_s, f.temperature_c, f.delta_t_c,
                                    f.rates_dps[axis], bias)
        kind = direction(d)
        for k in COLOURS:
            pts[k].append(np.column_stack([t[kind == k], y[kind == k]]))
        ax.plot(t, b, color="k", lw=1.0, label=None if i else
                "fitted model along the data (at each sample's T and ΔT)")
    for k, colour in COLOURS.items():
        xy = np.concatenate(pts[k]) if pts[k] else np.empty((0, 2))
        if len(xy):
            ax.scatter(xy[:, 0], xy[:, 1], s=4, color=colour, alpha=0.6,
                       label=f"measured, {k} ({_RULE[k]} °C), "
                       f"{BLOCK_S:g}-s means")
    r = cal.valid_range
    grid = np.linspace(r.t_min_c, r.t_max_c, 200)
    curve = cal.base_series(axis, grid, np.zeros_like(grid))
    ax.plot(grid, curve, color="k", ls="--", lw=1.2, label="fitted model at ΔT = 0 °C"
            + (" (polynomial only: effects need the history)" if cal.effect_names(axis)
               else ""))
    ax.set_xlabel("temperature T (°C)")
    ax.set_ylabel(f"rate {axis} at rest = bias (°/s)")
    ax.set_title(f"Bias against temperature, axis {axis} (model {cal.model.name})", fontsize=10)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def figure_rate_vs_time(cal: Calibration, feats: Sequence[RunFeatures], axis: str, *,
                        removed: Removed | None = None) -> Any:
    """One panel per run: raw and compensated 10-s means, T on a second y-axis."""
    runs = _runs(cal, feats, axis, removed)
    fig = _figure(figsize=(9, 2.4 * len(runs) + 0.6))
    for i, (f, bias) in enumerate(runs):
        ax = fig.add_subplot(len(runs), 1, i + 1)
        raw = f.rates_dps[axis]
        tm, y, c, temp = block_means(f.time_s, raw, raw - bias,
                                     f.temperature_c)
        ax.plot(tm / 60, y, color="0.45", lw=1.0, label="raw")
        ax.plot(tm / 60, c, color="tab:blue", lw=1.0, label="compensated (raw − fitted bias)")
        ax.axhline(0, color="k", lw=0.4)
        ax.set_ylabel(f"rate {axis} (°/s)")
        ax.set_title(f"{f.name}: {BLOCK_S:g}-s means", fontsize=9)
        tx = ax.twinx()
        tx.plot(tm / 60, temp, color="tab:orange", lw=1.0, ls=":", label="temperature T")
        tx.set_ylabel("T (°C)", color="tab:orange")
        if i == 0:
            lines = ax.get_lines()[:2] + tx.get_lines()
            ax.legend(lines, [ln.get_label() for ln in lines], fontsize=7, loc="upper right")
        if i == len(runs) - 1:
            ax.set_xlabel("time (min)")
    fig.tight_layout()
    return fig


def figure_residual_histogram(cal: Calibration, feats: Sequence[RunFeatures], axis: str, *,
                              removed: Removed | None = None) -> Any:
    """Raw and compensated output of all runs pooled (every sample), RMS in the legend."""
    runs = _runs(cal, feats, axis, removed)
    raw = np.concatenate([f.rates_dps[axis] for f, _ in runs])
    comp = np.concatenate([f.rates_dps[axis] - bias for f, bias in runs])
    lo, hi = np.percentile(np.concatenate([raw, comp]), [0.1, 99.9])
    bins = np.linspace(lo, hi, 80)
    fig = _figure(figsize=(7, 4.2))
    ax = fig.add_subplot()
    for v, label, colour in ((raw, "raw", "0.45"), (comp, "compensated", "tab:blue")):
        rms = float(np.sqrt(np.mean(v * v)))
        ax.hist(v, bins=bins, histtype="step", lw=1.4, color=colour,
                label=f"{label}: RMS {rms:.4g} °/s, mean {np.mean(v):+.4f} °/s")
    ax.axvline(0, color="k", lw=0.4)
    ax.set_xlabel(f"rate {axis} at rest (°/s; 0.1–99.9 % shown)")
    ax.set_ylabel("samples per bin")
    ax.set_title(f"Output at rest, axis {axis}, {len(runs)} runs, {raw.size} samples",
                 fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


FIGURES = (("bias_vs_temperature", figure_bias_vs_temperature),
           ("rate_vs_time", figure_rate_vs_time),
           ("residual_histogram", figure_residual_histogram))


def write_fit_report(cal: Calibration, feats: Sequence[RunFeatures], directory: Path, *,
                     title: str, calibration_path: str, zero: ZeroConfig | None = None) -> Path:
    """Write every axis' figures and ``report.md`` into ``directory``; the index path.
    ``zero``: the bias removed includes the boot-time zero (``evaluate --zero``)."""
    removed = [removed_bias(cal, f, zero=zero) for f in feats]
    axes = [a for a in cal.axes if any(a in f.rates_dps for f in feats)]
    lines = [f"# {title}", "", f"Calibration `{calibration_path}`: model {cal.model.name}, "
             f"runs: {', '.join(f.name for f in feats)}.", "",
             f"Figures show {BLOCK_S:g}-s means (the histograms: every sample). The fitted "
             "model depends on ΔT as well as T, so against T it is drawn along the data "
             "(one path per run) and, dashed, at ΔT = 0 °C. Heating/cooling: estimated "
             f"ΔT ≥ {STEADY_DT_C:g} °C / ≤ −{STEADY_DT_C:g} °C."
             + ("" if zero is None else " The bias removed includes the boot-time zero "
                f"({', '.join(f'{k}={v:g}' for k, v in zero.to_dict().items())})."), "",
             "| run | axis | raw RMS (°/s) | compensated RMS (°/s) |", "|---|---|---|---|"]
    for f, rb in zip(feats, removed, strict=True):
        for s in score(cal, f, removed=rb):
            lines.append(f"| {s.run} | {s.axis} | {s.raw.rms_dps:.4g} | "
                         f"{s.compensated.rms_dps:.4g} |")
    for axis in axes:
        lines += ["", f"## Axis {axis}", ""]
        for stem, make in FIGURES:
            name = f"{stem}_{axis}.png"
            make(cal, feats, axis, removed=removed).savefig(directory / name, dpi=100)
            lines.append(f"![{stem} {axis}]({name})")
    md = directory / "report.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md


__all__ = ["FIGURES", "block_means", "direction", "figure_bias_vs_temperature",
           "figure_rate_vs_time", "figure_residual_histogram", "write_fit_report"]
