"""``export_calibration``: the diagnosis' extended model as a calibration, effects
selected per axis (independent generator, seeded)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose, synth_runs
from gyrotherm.analysis._diagnose import export_calibration


def test_each_axis_gets_its_own_effects() -> None:
    cfg = SynthConfig(duration_s=6000.0, rate_hz=10.0)
    runs, truth = synth_runs(replace(cfg, effects={"warmup": {}}), n_runs=4, seed=101)
    # the same runs without the warm-up (same temperatures and noise: the generator
    # draws the effect from its own stream) as axis y
    plain, _ = synth_runs(cfg, n_runs=4, seed=101)
    assert all(np.array_equal(r.temperature_c, p.temperature_c) for r, p in zip(runs, plain,
                                                                                 strict=True))
    runs = [replace(r, rates_dps={"x": r.rates_dps["x"], "y": p.rates_dps["x"]})
            for r, p in zip(runs, plain, strict=True)]
    result = diagnose(runs, axis="x", simulate=False)
    assert [f.effect for f in result.findings] == ["warmup"]
    fitted = export_calibration(runs, result)
    cal = fitted.calibration
    assert cal.version == 2 and cal.axes == ("x", "y")
    assert cal.effect_names("x") == ("warmup",) and cal.effect_names("y") == ()
    warm = cal.effects_of("x").warmup
    assert warm is not None
    assert warm.amplitude_dps == pytest.approx(truth.effects["warmup"]["amplitude_dps"], rel=0.3)
    assert warm.tau_s == pytest.approx(truth.effects["warmup"]["tau_s"], rel=0.3)
    assert fitted.heldout_rms_dps["x"] < fitted.baseline_heldout_rms_dps["x"] / 1.1
    assert fitted.heldout_rms_dps["y"] == fitted.baseline_heldout_rms_dps["y"]
    prov = cal.provenance["diagnosis"]["axes"]
    assert prov["x"]["effects"] == ["warmup"] and prov["y"]["effects"] == []
    # the compensator removes the warm-up on x: its error against the true bias over
    # the first 10 min is a fraction of the injected warm-up's own variation there
    from gyrotherm.compensation import features

    f = features(runs[0], cal.estimator)
    out = cal.compensator().series(f.time_s, f.temperature_c, f.delta_t_c)
    injected = runs[0].true_bias_dps["x"] - plain[0].true_bias_dps["x"]
    error = runs[0].true_bias_dps["x"] - out.bias_dps["x"]
    early = f.time_s < 600.0
    assert np.std(error[early]) < 0.4 * np.std(injected[early])  # 0.24 at seed 101
