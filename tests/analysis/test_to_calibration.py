"""``export_calibration``: the diagnosis' extended model as a calibration, effects
selected per axis (independent generator, seeded)."""

from __future__ import annotations

import math
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


def test_add_bias_equals_the_online_kernel_on_uniform_and_jittered_grids() -> None:
    """add_bias takes the vectorised columns on the simulator's uniform grid and the
    kernel otherwise: both equal ExtendedModel.bias (the kernel) to 1e-9."""
    from gyrotherm.analysis import add_bias
    from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
    from gyrotherm.compensation import Scaling
    from gyrotherm.sim import ChamberProfile, GyroParams, simulate

    profile = ChamberProfile.from_pairs([(0, 20), (600, 20), (1500, 45), (2100, 45),
                                         (3000, 25), (3600, 25)])
    run = simulate(profile, name="s", gyro=GyroParams().quiet(), rate_hz=5.0, seed=2)
    model = ExtendedModel(Scaling(30.0, 15.0, 5.0),
                          {"thermal_lag": 60.0, "hysteresis": 0.4, "warmup": 300.0},
                          (*BASE_COLUMNS, "hysteresis", "warmup"),
                          (0.01, 0.03, 0.02, 0.002, 0.05, -0.04), intercept_dps=0.1)
    temp, dtemp = run.extra["true_temperature_c"], run.extra["true_delta_t_c"]
    want = model.bias(run.time_s, temp, dtemp)
    added = add_bias(run, model, "x").rates_dps["x"] - run.rates_dps["x"]
    assert np.max(np.abs(added - want)) < 1e-9 and np.ptp(want) > 0.1
    rng = np.random.default_rng(3)
    jittered = replace(run, time_s=run.time_s + rng.uniform(0.0, 0.05, len(run)))
    added = add_bias(jittered, model, "x").rates_dps["x"] - run.rates_dps["x"]
    jittered_bias = model.bias(jittered.time_s, temp, dtemp)
    assert np.max(np.abs(added - jittered_bias)) < 1e-12  # (rate + b) − rate: rounding
    assert np.max(np.abs(jittered_bias - want)) > 1e-6  # the kernel saw the jitter


@pytest.mark.parametrize("variable", ["temperature_c", "delta_t_c", "time_since_power_on_s"])
def test_the_simulators_replay_applies_the_correction_as_the_vehicle_does(
        variable: str) -> None:
    """add_bias with a calibration's ``correction`` adds, on the simulator's truth, what
    the vehicle's online kernel adds for that correction to 1e-9 (knots inside and the
    run's range beyond them: clamped, constant outside); without it, nothing changes."""
    from gyrotherm.analysis import add_bias
    from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
    from gyrotherm.compensation import Scaling
    from gyrotherm.compensation._correction import Correction
    from gyrotherm.compensation._effects import Effects, EffectsKernel
    from gyrotherm.sim import ChamberProfile, GyroParams, simulate

    profile = ChamberProfile.from_pairs([(0, 20), (600, 20), (1500, 45), (2100, 45),
                                         (3000, 25), (3600, 25)])
    run = simulate(profile, name="s", gyro=GyroParams().quiet(), rate_hz=5.0, seed=2)
    model = ExtendedModel(Scaling(30.0, 15.0, 5.0), {}, BASE_COLUMNS,
                          (0.01, 0.03, 0.02, 0.002), intercept_dps=0.1)
    temp, dtemp = run.extra["true_temperature_c"], run.extra["true_delta_t_c"]
    v = {"temperature_c": temp, "delta_t_c": dtemp, "time_since_power_on_s": run.time_s}[
        variable]
    lo, hi = np.percentile(v, [10, 90])  # the run goes beyond the knots on both sides
    knots = tuple(float(k) for k in np.linspace(lo, hi, 9))
    corr = Correction(variable, knots, tuple(0.03 * math.sin(1.7 * i) for i in range(9)))
    vehicle = EffectsKernel(Effects(correction=corr)).series(run.time_s, temp, dtemp).bias_dps
    plain = add_bias(run, model, "x")
    corrected = add_bias(run, model, "x", correction=corr)
    added = corrected.true_bias_dps["x"] - plain.true_bias_dps["x"]
    assert np.max(np.abs(added - vehicle)) < 1e-9 and np.ptp(vehicle) > 0.04
    assert np.max(np.abs((corrected.rates_dps["x"] - plain.rates_dps["x"]) - added)) < 1e-12
    assert np.array_equal(plain.rates_dps["y"], corrected.rates_dps["y"])
