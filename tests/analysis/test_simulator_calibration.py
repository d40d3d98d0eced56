"""The simulator calibrated to the measurements (docs/findings.md §7).

Truths: Tang et al. 2013's printed Table 1/Table 2/Fig. 6 values and the BMI270
plateaus (measured data, second halves held out); the ΔT-ratio and its T* are
recomputed by hand from Table 1; a sinusoid's least-squares amplitude is known. The
held-out errors are computed here, seeded, for the defaults and the stored profiles.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.analysis._simcal import (
    FIT_ROWS,
    default_dt_ratio,
    score_tang,
)
from gyrotherm.analysis._simcal_bmi import (
    FS_HZ,
    fit_bmi,
    load_plateaus,
    score_bmi,
    sine_amplitude,
)
from gyrotherm.analysis._simcal_tang import (
    TANG_FIG6,
    TANG_TABLE1,
    fit_bow,
    measured_dt_ratio,
    ramp_residual_c,
    t_star_raw,
)
from gyrotherm.sim import ChamberModel, GyroParams
from gyrotherm.sim._profiles import (
    BMI270_SESSIONS,
    TANG_DT_SCALE,
    get_profile,
)

DATA = Path("/work/shared/data/measured/bmi270-peltier-laptop/bmi270_static_clean.csv")
for parent in Path(__file__).resolve().parents:
    if (parent.parent / "shared" / "data" / "measured").is_dir():
        DATA = parent.parent / "shared/data/measured/bmi270-peltier-laptop/bmi270_static_clean.csv"
        break
needs_data = pytest.mark.skipif(not DATA.is_file(), reason=f"measured data not at {DATA}")


def test_dt_ratio_and_scale_by_hand() -> None:
    # T* from the fit rows: minus the least-squares slope of a3 on a4, by hand
    a4 = np.array([TANG_TABLE1[m][3] for m in FIT_ROWS])
    a3 = np.array([TANG_TABLE1[m][2] for m in FIT_ROWS])
    slope = np.sum((a4 - a4.mean()) * (a3 - a3.mean())) / np.sum((a4 - a4.mean()) ** 2)
    assert t_star_raw(FIT_ROWS) == pytest.approx(-slope, rel=1e-12)
    a1, a2, a3_5, a4_5, _ = TANG_TABLE1[5]
    r5 = (a3_5 + a4_5 * -slope) / (a2 + 2 * a1 * -slope)
    assert measured_dt_ratio([5], t_star=-slope)[5] == pytest.approx(r5, rel=1e-12)
    # the default simulator's x axis at 15 °C: (0.05 − 0.0004·15)/(−0.010 + 2·1.2e-4·15)
    assert default_dt_ratio(GyroParams()) == pytest.approx(0.044 / -0.0064, rel=1e-12)
    r_fit = np.mean(list(measured_dt_ratio(FIT_ROWS, t_star=-slope).values()))
    assert TANG_DT_SCALE == pytest.approx(r_fit / (0.044 / -0.0064), rel=1e-5)


def test_bow_law_reproduces_fig6_on_other_seeds() -> None:
    model = fit_bow(seeds=range(3))
    for minutes, (_, res_c) in TANG_FIG6.items():
        assert ramp_residual_c(model, minutes, seeds=range(50, 56)) == pytest.approx(
            res_c, rel=0.05)
    # the default chamber gives the same residual on both ramps (docs/findings.md §3)
    default = [ramp_residual_c(ChamberModel(), m, seeds=range(50, 56)) for m in TANG_FIG6]
    assert abs(default[0] - default[1]) < 0.1


def test_sine_amplitude_recovers_a_known_line() -> None:
    rng = np.random.default_rng(8)
    t = np.arange(3000) / FS_HZ
    g = 0.07 * np.sin(2 * np.pi * 6.43 * t + 1.0) + rng.standard_normal(len(t)) * 0.2
    f, amp = sine_amplitude(g, 6.4)
    assert f == pytest.approx(6.43, abs=0.004)
    # least-squares amplitude error ≈ σ·√(2/n) = 0.005
    assert amp == pytest.approx(0.07, abs=0.015)


@needs_data
def test_bmi270_profile_is_the_first_half_fit_and_beats_defaults_on_second_halves() -> None:
    data = load_plateaus(DATA)
    fitted = fit_bmi(data)
    for s, (arw, lines) in BMI270_SESSIONS.items():
        for a, v in arw.items():
            assert fitted[s].arw_by_axis_deg_per_rth[a] == pytest.approx(v, rel=1e-3)
        got = [(ln.frequency_hz, *ln.amplitude_dps.items()) for ln in fitted[s].lines]
        assert [(round(f, 3), a, round(v, 4)) for f, (a, v) in got] == [
            (f, a, round(v, 4)) for f, a, v in lines]
    prof = get_profile("bmi270")
    seeds = range(301, 307)
    before = score_bmi({s: GyroParams() for s in data}, data, seeds=seeds)
    after = score_bmi(dict(prof.sessions), data, seeds=seeds)
    assert [b.name for b in before] == [a.name for a in after]
    for kind in ("std", "Allan", "line"):
        pairs = [(b, a) for b, a in zip(before, after, strict=True) if kind in b.name]
        assert len(pairs) in (6, 12)
        if kind != "Allan":  # the noise level and the lines: no plateau-axis worse
            for b, a in pairs:
                assert a.error <= b.error + 1e-12, (b.name, b.error, a.error)
        mean_b = np.mean([b.error for b, _ in pairs])
        mean_a = np.mean([a.error for _, a in pairs])
        assert mean_b / mean_a > 1.5, (kind, mean_b, mean_a)
    mean_b = np.mean([b.error for b in before])
    mean_a = np.mean([a.error for a in after])
    assert mean_b / mean_a > 2.5, (mean_b, mean_a)


def test_tang2013_profile_beats_defaults_on_held_out_statistics() -> None:
    prof = get_profile("tang2013")
    seeds = range(401, 403)
    before = score_tang(GyroParams(), ChamberModel(), seeds=seeds)
    after = score_tang(prof.gyro, prof.chamber, seeds=seeds)
    held = [(b, a) for b, a in zip(before, after, strict=True) if b.part == "held out"]
    assert len(held) == 7
    by_name = {b.name: (b, a) for b, a in held}
    # the 5-min temperature-only model: 0.40 °/s by default against Tang's 0.0598
    b5, a5 = by_name["Table 2 t2 5 min: RMS (°/s)"]
    assert b5.simulated > 4 * b5.measured and a5.error < b5.error / 2
    mean_b = np.mean([b.error for b, _ in held])
    mean_a = np.mean([a.error for _, a in held])
    assert mean_a < mean_b / 2, (mean_b, mean_a)
    assert all(math.isfinite(a.error) for _, a in held)
