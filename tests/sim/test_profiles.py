"""Simulator profiles and the optional physics they switch on.

Truths: the default profile is the simulator as it was (same seed → the same bytes as
before the optional physics existed: digest taken at commit 5339817, and the run
equals the one with no profile at all); a bow b·(r/r_ref)^p at mid-ramp is
hand-computable; a sinusoid of amplitude A has std A/√2; white noise N (°/√h) at
f_s has per-sample std N/60·√f_s (IEEE Std 952-1997); the CLI's --profile selects it.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm._errors import ConfigError
from gyrotherm.cli import main
from gyrotherm.codecs import read_run
from gyrotherm.sim import ChamberModel, ChamberProfile, GyroParams, chamber_runs, simulate
from gyrotherm.sim._lines import SpectralLine
from gyrotherm.sim._profiles import PROFILE_NAMES, get_profile

#: sha256 of chamber_runs([5, 30], seed=3, rate_hz=2, hold_s=600) (rates x, y, z,
#: temperature, chamber air per run), computed with the simulator at commit 5339817,
#: before any optional physics was added
DIGEST_AT_5339817 = "c708bac8f18aca335d19b6680445d6e270ab66ebdac164f57aca85615f1965bf"


def _digest(runs: list) -> str:  # type: ignore[type-arg]
    h = hashlib.sha256()
    for r in runs:
        for a in ("x", "y", "z"):
            h.update(r.rates_dps[a].tobytes())
        h.update(r.temperature_c.tobytes())
        h.update(r.chamber_c.tobytes())
    return h.hexdigest()


def test_default_profile_reproduces_the_old_simulator_exactly() -> None:
    prof = get_profile("default")
    runs = chamber_runs([5, 30], seed=3, rate_hz=2.0, hold_s=600.0, gyro=prof.gyro,
                        chamber=prof.chamber)
    assert _digest(runs) == DIGEST_AT_5339817
    plain = chamber_runs([5, 30], seed=3, rate_hz=2.0, hold_s=600.0)
    assert _digest(plain) == DIGEST_AT_5339817


def test_profiles_are_distinct_and_unknown_names_are_config_errors() -> None:
    assert set(PROFILE_NAMES) == {"default", "tang2013", "bmi270"}
    tang = get_profile("tang2013")
    # only the white noise beat its nulls (docs/findings.md §7); the rest is the default
    assert tang.gyro.bias == GyroParams().bias and tang.chamber == ChamberModel()
    assert tang.gyro.arw_deg_per_rth != GyroParams().arw_deg_per_rth
    bmi = get_profile("bmi270")
    assert set(bmi.sessions) == {"cold", "hot"} and not bmi.gyro.lines
    assert all(s.lines for s in bmi.sessions.values())  # per-session descriptions
    assert bmi.gyro.rate_lsb_dps == pytest.approx(1 / 16.4)
    with pytest.raises(ConfigError, match="unknown; choose from default, tang2013, bmi270"):
        get_profile("nope")


def test_bow_grows_with_ramp_rate_as_configured() -> None:
    # 0 → 70 °C over 35 min = 2 °C/min; bow 2·(2/1)^0.5 = 2√2 °C at mid-ramp (u = ½)
    model = ChamberModel(lag_s=0.0, bow_c=2.0, noise_c=0.0, bow_rate_exponent=0.5,
                         bow_reference_rate_c_per_min=1.0)
    prof = ChamberProfile.from_pairs([(0.0, 0.0), (2100.0, 70.0)])
    t = np.array([0.0, 1050.0, 2100.0])
    air = prof.realise(t, model, np.random.default_rng(0))
    assert air[1] == pytest.approx(35.0 + 2.0 * math.sqrt(2.0), abs=1e-9)
    assert model.bow_for_rate_c(-2.0) == pytest.approx(2.0 * math.sqrt(2.0))
    assert ChamberModel().bow_for_rate_c(5.0) == ChamberModel().bow_c  # default: off
    with pytest.raises(ConfigError, match="bow_reference_rate_c_per_min must be > 0"):
        ChamberModel(bow_reference_rate_c_per_min=0.0)


def test_lines_and_per_axis_white_noise_have_their_textbook_variance() -> None:
    quiet = GyroParams().quiet()
    prof = ChamberProfile.from_pairs([(0.0, 20.0), (2000.0, 20.0)])
    still = ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0)
    line = replace(quiet, lines=(SpectralLine(3.0, {"x": 0.2}),))
    run = simulate(prof, name="l", gyro=line, chamber=still, rate_hz=50.0, seed=4)
    x = run.rates_dps["x"] - run.true_bias_dps["x"]
    assert np.std(x) == pytest.approx(0.2 / math.sqrt(2), rel=1e-3)
    assert np.allclose(run.rates_dps["y"], run.true_bias_dps["y"])  # no line on y
    white = replace(quiet, arw_by_axis_deg_per_rth={"z": 3.0})
    run = simulate(prof, name="w", gyro=white, chamber=still, rate_hz=50.0, seed=5)
    z = run.rates_dps["z"] - run.true_bias_dps["z"]
    # 100 001 samples: the sample std is within ±1 % (≈ 4.5 σ of its 0.22 % spread)
    assert np.std(z) == pytest.approx(3.0 / 60 * math.sqrt(50.0), rel=0.01)
    with pytest.raises(ConfigError, match="frequency_hz must be > 0"):
        SpectralLine(0.0, {"x": 1.0})
    with pytest.raises(ConfigError, match=r"arw_by_axis_deg_per_rth\['x'\] must be ≥ 0"):
        GyroParams(arw_by_axis_deg_per_rth={"x": -1.0})


def test_cli_profile_selects_the_calibrated_simulator(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["-q", "sim", "chamber", "--heating-min", "5", "--seed", "2", "--rate-hz", "1",
            "--hold-s", "600"]
    for name in ("none", "default", "tang2013"):
        extra = [] if name == "none" else ["--profile", name]
        assert main([*args, "--out", str(tmp_path / name), *extra]) == 0
    read = {n: read_run(tmp_path / n / "heat-05min.csv") for n in ("none", "default", "tang2013")}
    assert np.array_equal(read["none"].rates_dps["x"], read["default"].rates_dps["x"])
    assert not np.array_equal(read["none"].rates_dps["x"], read["tang2013"].rates_dps["x"])
    capsys.readouterr()
    assert main(["-q", "paper", "--rate-hz", "1", "--profile", "tang2013"]) == 0
    out = capsys.readouterr().out
    truth = next(line for line in out.splitlines() if line.startswith("truth"))
    dt = get_profile("tang2013").gyro.bias.coefficients["x"]["dT"]
    assert float(truth.split()[3]) == pytest.approx(dt, rel=1e-5)
