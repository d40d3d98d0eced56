"""The diagnosis figures (src/gyrotherm/analysis/_figures.py) checked for what they
claim, on the Figure objects: every run drawn, distinct labels and styles, the data
behind each bar and line, legends that match what is drawn."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose, synth_runs
from gyrotherm.analysis._diagnose import Diagnosis
from gyrotherm.analysis._figures import (
    figure_allan,
    figure_before_after,
    figure_measured_vs_simulated,
    figure_residual_vs_temperature,
    raw_rms,
)


@pytest.fixture(scope="module")
def diagnosis() -> Diagnosis:
    runs, _ = synth_runs(SynthConfig(duration_s=2400.0, rate_hz=5.0,
                                     effects={"drift": {"slope_dps_per_h": 0.15}}),
                         n_runs=4, seed=9)
    return diagnose(runs, replays=2, seed=1)


def _legend(ax: Any) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _means_60s(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    k = np.floor(t / 60.0)
    keys, inv, counts = np.unique(k, return_inverse=True, return_counts=True)
    ok = counts >= 10
    return (keys[ok] + 0.5) * 60.0, (np.bincount(inv, weights=y) / counts)[ok]


def test_before_after(diagnosis: Diagnosis) -> None:
    d = diagnosis
    names = [p.name for p in d.prepared]
    n = len(names)
    fig = figure_before_after(d)
    top, bottom = fig.axes
    raw, raw_all = raw_rms(d)
    assert len(top.patches) == 3 * n
    series = [top.patches[k * n:(k + 1) * n] for k in range(3)]
    for bars, want in zip(series, (raw, d.heldout_baseline, d.heldout_extended), strict=True):
        np.testing.assert_allclose([b.get_height() for b in bars], want)
    # distinct colour and hatch per series; side by side, never one bar over another
    assert len({(tuple(s[0].get_facecolor()), s[0].get_hatch()) for s in series}) == 3
    for i in range(n):
        spans = sorted((s[i].get_x(), s[i].get_x() + s[i].get_width()) for s in series)
        assert all(a[1] <= b[0] + 1e-12 for a, b in itertools.pairwise(spans))
    labels = _legend(top)
    assert labels == [f"raw output, own mean removed: all runs {raw_all:.4g}",
                      f"paper (baseline), held out: all runs {d.baseline_heldout_rms_dps:.4g}",
                      f"extended ({d.extended.name}), held out: all runs "
                      f"{d.extended_heldout_rms_dps:.4g}"]
    assert top.get_yscale() == "log"  # a 20× spread stays readable
    lo, hi = top.get_ylim()
    heights = [b.get_height() for b in top.patches]
    assert lo < min(heights) and max(heights) < hi
    assert "°/s" in top.get_ylabel() and "°/s" in bottom.get_ylabel()
    # the difference panel: extended − paper per run, every run labelled
    np.testing.assert_allclose([b.get_height() for b in bottom.patches],
                               np.subtract(d.heldout_extended, d.heldout_baseline))
    assert [t.get_text() for t in bottom.get_xticklabels()] == names
    assert all(b.get_height() < 0 for b in bottom.patches)  # drift found: every run better


def test_measured_vs_simulated_every_run_in_distinct_styles(diagnosis: Diagnosis) -> None:
    d = diagnosis
    sim = d.simulation
    assert sim is not None
    fig = figure_measured_vs_simulated(d)
    titled = {ax.get_title(): ax for ax in fig.axes if ax.get_title()}
    assert sorted(titled) == sorted(p.name for p in d.prepared)  # every run, not three
    diffs = [ax for ax in fig.axes if ax.get_ylabel() == "simulated − measured (°/s)"]
    assert len(diffs) == len(d.prepared)
    for j, p in enumerate(d.prepared):
        ax = titled[p.name]
        lines = ax.get_lines()
        assert [ln.get_label() for ln in lines] == [
            "measured", "simulated, paper model", f"simulated, extended ({d.extended.name})"]
        assert len({(ln.get_color(), ln.get_linestyle()) for ln in lines}) == 3
        mx, my = _means_60s(p.time_s, p.rate_dps - d.baseline.offsets_dps[p.name])
        np.testing.assert_allclose(lines[0].get_xdata(), mx / 60)
        np.testing.assert_allclose(lines[0].get_ydata(), my)
        q = sim.extended_prepared[j]
        sx, sy = _means_60s(q.time_s, q.rate_dps - np.mean(q.rate_dps) + np.mean(
            p.rate_dps - d.baseline.offsets_dps[p.name]))
        _common, i_s, i_m = np.intersect1d(sx, mx, return_indices=True)
        ext_diff = [ln for ln in diffs[j].get_lines() if "extended" in str(ln.get_label())]
        np.testing.assert_allclose(ext_diff[0].get_ydata(), sy[i_s] - my[i_m])
    assert _legend(diffs[0]) == ["simulated, paper model − measured",
                                 f"simulated, extended ({d.extended.name}) − measured"]


def test_residual_vs_temperature_legend_matches_what_is_drawn(diagnosis: Diagnosis) -> None:
    fig = figure_residual_vs_temperature(diagnosis)
    (ax,) = fig.axes
    drawn = [a.get_label() for a in [*ax.collections, *ax.get_lines()]
             if not str(a.get_label()).startswith("_")]
    assert sorted(_legend(ax)) == sorted(drawn)
    assert "heating (last move up): 2 °C bin means" in drawn
    assert "cooling (last move down): 1-s blocks, every 5th" in drawn
    n_points = sum(len(c.get_offsets()) for c in ax.collections)
    blocks = sum(len(p) for p in diagnosis.prepared)
    assert blocks / 5 <= n_points <= blocks / 5 + 3


def test_allan_curves_distinct(diagnosis: Diagnosis) -> None:
    (ax,) = figure_allan(diagnosis).axes
    lines = ax.get_lines()
    assert [ln.get_label() for ln in lines] == [
        "measured, paper residual", "simulated, paper residual", "measured, extended residual"]
    assert len({(ln.get_color(), ln.get_linestyle()) for ln in lines}) == 3
    assert ax.get_xscale() == ax.get_yscale() == "log"
