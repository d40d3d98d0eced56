"""``fit --report`` / ``evaluate --report`` figures (src/gyrotherm/cli/_plots.py): each
checked for what it claims, on the Figure objects the plotting functions return."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from gyrotherm.cli import main
from gyrotherm.cli._plots import (
    BLOCK_S,
    COLOURS,
    STEADY_DT_C,
    block_means,
    figure_bias_vs_temperature,
    figure_rate_vs_time,
    figure_residual_histogram,
)
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import Calibration, RunFeatures, features, fit
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, chamber_runs

AXIS = "x"


@pytest.fixture(scope="module")
def runs() -> list[Run]:
    heat = chamber_runs([5, 30], seed=2, rate_hz=1.0, hold_s=600)
    h = heat[1]  # the same run played backwards: a cooling run through the real estimator
    cool = Run(name="cool-30min", time_s=h.time_s, temperature_c=h.temperature_c[::-1].copy(),
               rates_dps={a: v[::-1].copy() for a, v in h.rates_dps.items()})
    return [*heat, cool]


@pytest.fixture(scope="module")
def fitted(runs: list[Run]) -> tuple[Calibration, list[RunFeatures]]:
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    feats = [features(r, est) for r in runs]
    return fit(feats[:2], "paper", estimator=est), feats  # fitted on the heating runs


def _blocks(cal: Calibration, f: RunFeatures) -> list[np.ndarray]:
    bias, _ = cal.bias_series(AXIS, f.temperature_c, f.delta_t_c, f.time_s)
    return block_means(f.time_s, f.temperature_c, f.delta_t_c, f.rates_dps[AXIS], bias)


def _legend(ax: object) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]  # type: ignore[attr-defined]


def test_bias_against_temperature(fitted: tuple[Calibration, list[RunFeatures]]) -> None:
    cal, feats = fitted
    fig = figure_bias_vs_temperature(cal, feats, AXIS)
    (ax,) = fig.axes
    assert ax.get_xlabel() == "temperature T (°C)"
    assert ax.get_ylabel() == f"rate {AXIS} at rest = bias (°/s)"
    labels = _legend(ax)
    assert f"measured, heating (ΔT ≥ {STEADY_DT_C:g} °C), {BLOCK_S:g}-s means" in labels
    assert f"measured, cooling (ΔT ≤ −{STEADY_DT_C:g} °C), {BLOCK_S:g}-s means" in labels
    assert "fitted model along the data (at each sample's T and ΔT)" in labels
    assert "fitted model at ΔT = 0 °C" in labels
    blocks = [_blocks(cal, f) for f in feats]
    # points: every block mean, coloured by the sign of its ΔT, nothing else
    by_colour = {tuple(c.get_facecolor()[0][:3]): c.get_offsets() for c in ax.collections}
    for kind, test in (("heating", lambda d: d >= STEADY_DT_C),
                       ("cooling", lambda d: d <= -STEADY_DT_C)):
        want = np.concatenate([np.column_stack([b[1][test(b[2])], b[3][test(b[2])]])
                               for b in blocks])
        got = by_colour[tuple(to_rgba(COLOURS[kind])[:3])]
        assert len(want) > 20
        np.testing.assert_allclose(np.asarray(got), want)
    assert sum(len(c.get_offsets()) for c in ax.collections) == sum(len(b[0]) for b in blocks)
    # one model path per run, drawn along the data; then the dashed ΔT = 0 curve
    solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    assert len(solid) == len(feats)
    for ln, b in zip(solid, blocks, strict=True):
        np.testing.assert_allclose(ln.get_xdata(), b[1])
        np.testing.assert_allclose(ln.get_ydata(), b[4])
    (dashed,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    x = np.asarray(dashed.get_xdata())
    assert (x.min(), x.max()) == (cal.valid_range.t_min_c, cal.valid_range.t_max_c)
    np.testing.assert_allclose(dashed.get_ydata(), cal.base_series(AXIS, x, 0 * x))
    # on the runs it was fitted to, the model follows the measured means
    y = np.concatenate([b[3] for b in blocks[:2]])
    model = np.concatenate([b[4] for b in blocks[:2]])
    assert np.sqrt(np.mean((y - model) ** 2)) < 0.2 * np.std(y)


def test_raw_and_compensated_against_time(
        fitted: tuple[Calibration, list[RunFeatures]]) -> None:
    cal, feats = fitted
    fig = figure_rate_vs_time(cal, feats, AXIS)
    main_axes = [ax for ax in fig.axes if ax.get_ylabel() == f"rate {AXIS} (°/s)"]
    twins = [ax for ax in fig.axes if ax.get_ylabel() == "T (°C)"]
    assert len(main_axes) == len(twins) == len(feats)  # every run, T on a second axis
    assert main_axes[-1].get_xlabel() == "time (min)"
    assert _legend(main_axes[0]) == ["raw", "compensated (raw − fitted bias)",
                                     "temperature T"]
    for i, (ax, tx, f) in enumerate(zip(main_axes, twins, feats, strict=True)):
        assert ax.get_title().startswith(f.name)
        raw, comp = ax.get_lines()[:2]
        tm, y, temp = block_means(f.time_s, f.rates_dps[AXIS], f.temperature_c)
        np.testing.assert_allclose(raw.get_xdata(), tm / 60)
        np.testing.assert_allclose(raw.get_ydata(), y)
        (tline,) = tx.get_lines()
        np.testing.assert_allclose(tline.get_ydata(), temp)
        styles = {(ln.get_color(), ln.get_linestyle()) for ln in (raw, comp, tline)}
        assert len(styles) == 3
        c = np.asarray(comp.get_ydata())
        np.testing.assert_allclose(y - c, block_means(f.time_s, cal.bias_series(
            AXIS, f.temperature_c, f.delta_t_c, f.time_s)[0])[1], atol=1e-12)
        if i < 2:  # a fitted run: compensated well below raw
            assert np.sqrt(np.mean(c * c)) < 0.3 * np.sqrt(np.mean(y * y))


def test_residual_histograms(fitted: tuple[Calibration, list[RunFeatures]]) -> None:
    cal, feats = fitted
    fig = figure_residual_histogram(cal, feats, AXIS)
    (ax,) = fig.axes
    raw = np.concatenate([f.rates_dps[AXIS] for f in feats])
    comp = np.concatenate([f.rates_dps[AXIS] - cal.bias_series(
        AXIS, f.temperature_c, f.delta_t_c, f.time_s)[0] for f in feats])
    labels = _legend(ax)
    for name, v, label in (("raw", raw, labels[0]), ("compensated", comp, labels[1])):
        m = re.fullmatch(rf"{name}: RMS (\S+) °/s, mean (\S+) °/s", label)
        assert m, label
        assert float(m[1]) == pytest.approx(np.sqrt(np.mean(v * v)), rel=1e-3)
        assert float(m[2]) == pytest.approx(np.mean(v), abs=1e-4)
    assert f"{len(feats)} runs, {raw.size} samples" in ax.get_title()
    assert len(ax.patches) == 2  # two step histograms
    assert ax.get_xlabel().startswith(f"rate {AXIS} at rest (°/s")


def test_fit_and_evaluate_write_the_report(runs: list[Run], tmp_path: Path) -> None:
    paths = [str(write_run(r, tmp_path / f"{r.name}.csv")) for r in runs]
    cal = tmp_path / "cal.json"
    assert main(["-q", "fit", *paths[:2], "--out", str(cal), "--report",
                 str(tmp_path / "fit" / "rep"), "--no-validation"]) == 0
    assert main(["-q", "evaluate", str(cal), paths[2], "--report", str(tmp_path / "ev")]) == 0
    for rep, names in ((tmp_path / "fit" / "rep", ["heat-05min", "heat-30min"]),
                       (tmp_path / "ev", ["cool-30min"])):
        md = (rep / "report.md").read_text(encoding="utf-8")
        linked = re.findall(r"!\[[^]]*\]\(([^)]+)\)", md)
        assert sorted(linked) == sorted(f"{s}_{a}.png" for a in "xyz" for s in (
            "bias_vs_temperature", "rate_vs_time", "residual_histogram"))
        for name in linked:
            assert (rep / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        for n in names:
            assert f"| {n} | x |" in md


def test_version2_calibration_drawn_with_its_effects(
        fitted: tuple[Calibration, list[RunFeatures]]) -> None:
    """With effects the model along the data includes them (the online compensator's
    bias); the ΔT = 0 curve is the polynomial alone and says so."""
    from dataclasses import replace

    from gyrotherm.compensation._effects import Effects, Warmup

    cal, feats = fitted
    v2 = replace(cal, effects={AXIS: Effects(warmup=Warmup(amplitude_dps=0.2, tau_s=300.0))})
    assert v2.version == 2
    (ax,) = figure_bias_vs_temperature(v2, feats, AXIS).axes
    assert "fitted model at ΔT = 0 °C (polynomial only: effects need the history)" in \
        _legend(ax)
    solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    f = feats[0]
    with_effects = v2.bias_series(AXIS, f.temperature_c, f.delta_t_c, f.time_s)[0]
    np.testing.assert_allclose(solid[0].get_ydata(), block_means(f.time_s, with_effects)[1])
    assert not np.allclose(solid[0].get_ydata(), _blocks(cal, f)[4])  # the warm-up shows
