"""The simulator calibrated to the BMI270 plateaus (docs/findings.md §1, §7).

Data: ``bmi270_static_clean.csv`` of the BMI270 data set (© 2026 Ganesh Yerramsetti,
MIT; see its SOURCE.md): two isothermal plateaus (cold ≈ 13 °C, hot ≈ 48 °C), 50 Hz
nominal, output quantum 1/16.4 °/s. The two sessions share no spectral line and
differ in noise level per axis (§1), so a per-run (session) setting is fitted on the
FIRST half of each plateau and scored on the SECOND half (held out):

* lines: in each band (0.1–2, 2–12, 12–25 Hz) the strongest Welch PSD bin
  (nperseg 512), kept if it is ≥ 4× the band's median; its amplitude A (°/s) by
  least squares of a sinusoid at that frequency, refined on a 0.002-Hz grid
  (±0.1 Hz) to the largest A;
* white level: σ_w² = var − Σ A²/2 − q²/12 (q the output quantum), N = σ_w·60/√f_s.

Scored per plateau and axis on the held-out half (simulated: mean over seeds of
isothermal plateaus of the same length, quantised to q): e = |ln(sim/measured)| of
the std and of the Allan deviation at τ = 0.1, 1 s; and the fraction of the held-out
half's lines (same rule) that the simulation does not show within ±0.5 Hz.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import welch

from gyrotherm._errors import ConfigError
from gyrotherm.analysis._simcal import Score
from gyrotherm.analysis._stats import allan_deviation
from gyrotherm.sim import ChamberModel, ChamberProfile, GyroParams, simulate
from gyrotherm.sim._lines import SpectralLine

FS_HZ = 50.0
LSB_DPS = 1 / 16.4
AXES = ("x", "y", "z")
BANDS_HZ = ((0.1, 2.0), (2.0, 12.0), (12.0, 25.0))
PROMINENCE = 4.0
TOLERANCE_HZ = 0.5
ALLAN_TAUS_S = (0.1, 1.0)
FloatArray = np.ndarray


def load_plateaus(path: Path) -> dict[str, dict[str, FloatArray]]:
    """{plateau: {"temp_c": …, "x": …, "y": …, "z": …}} from the clean CSV (°/s, °C)."""
    if not path.is_file():
        raise ConfigError(f"BMI270 data: {path} not found (see the data set's SOURCE.md)")
    raw = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    out = {}
    for s in ("cold", "hot"):
        d = raw[raw["segment"] == s]
        out[s] = {"temp_c": d["temp_degC"].astype(float),
                  **{a: d[f"gyro_{a}_dps"].astype(float) for a in AXES}}
    return out


def lines_in(g: FloatArray) -> list[tuple[float, float]]:
    """(frequency Hz, prominence) of the band maxima that stand ≥ 4× above the median."""
    f, p = welch(g - g.mean(), fs=FS_HZ, nperseg=min(512, len(g)))
    out = []
    for lo, hi in BANDS_HZ:
        sel = (f >= lo) & (f < hi)
        i = int(np.argmax(p[sel]))
        prom = float(p[sel][i] / np.median(p[sel]))
        if prom >= PROMINENCE:
            out.append((float(f[sel][i]), prom))
    return out


def sine_amplitude(g: FloatArray, f0_hz: float) -> tuple[float, float]:
    """(frequency, amplitude A °/s) of the best least-squares sinusoid within ±0.1 Hz."""
    t = np.arange(len(g)) / FS_HZ
    x = g - g.mean()
    best = (f0_hz, 0.0)
    for f in np.arange(f0_hz - 0.1, f0_hz + 0.1 + 1e-9, 0.002):
        design = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
        coef, *_ = np.linalg.lstsq(design, x, rcond=None)
        amp = float(np.hypot(*coef))
        if amp > best[1]:
            best = (float(f), amp)
    return best


def fit_session(data: Mapping[str, FloatArray]) -> GyroParams:
    """Per-axis white level and lines of one plateau half (module docstring)."""
    lines: list[SpectralLine] = []
    arw: dict[str, float] = {}
    for a in AXES:
        g = data[a]
        power = 0.0
        for f0, _ in lines_in(g):
            f, amp = sine_amplitude(g, f0)
            lines.append(SpectralLine(frequency_hz=f, amplitude_dps={a: amp}))
            power += amp**2 / 2
        white = math.sqrt(max(float(np.var(g)) - power - LSB_DPS**2 / 12, 0.0))
        arw[a] = white * 60 / math.sqrt(FS_HZ)
    base = GyroParams().quiet()
    return replace(base, rate_lsb_dps=LSB_DPS, arw_by_axis_deg_per_rth=arw,
                   lines=tuple(lines))


def simulate_plateau(gyro: GyroParams, *, axis: str, n: int, temp_c: float,
                     seed: int) -> FloatArray:
    """n samples (50 Hz) of ``gyro``'s rate on ``axis`` at constant ``temp_c``, bias removed."""
    profile = ChamberProfile.from_pairs([(0.0, temp_c), (n / FS_HZ, temp_c)])
    still = ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0)
    run = simulate(profile, name="plateau", gyro=replace(gyro, axes=(axis,)), chamber=still,
                   rate_hz=FS_HZ, seed=seed)
    return np.asarray(run.rates_dps[axis][:n] - run.true_bias_dps[axis][:n], dtype=float)


def _half(d: Mapping[str, FloatArray], second: bool) -> dict[str, FloatArray]:
    n = len(d["x"]) // 2
    return {k: (v[n:] if second else v[:n]) for k, v in d.items()}


def score_bmi(sessions: Mapping[str, GyroParams], data: Mapping[str, Mapping[str, FloatArray]],
              *, seeds: Sequence[int]) -> tuple[Score, ...]:
    """Held-out (second-half) errors of the simulator, per plateau and axis, with
    ``sessions[plateau]`` the gyro of that plateau."""
    out = []
    for s, d in data.items():
        held = _half(d, second=True)
        temp = float(np.mean(held["temp_c"]))
        for a in AXES:
            g = held[a]
            sims = [simulate_plateau(sessions[s], axis=a, n=len(g), temp_c=temp, seed=k)
                    for k in seeds]
            std_s = float(np.mean([np.std(x) for x in sims]))
            std_m = float(np.std(g))
            out.append(Score(f"{s} {a}: std (°/s)", "held out", std_m, std_s,
                             abs(math.log(std_s / std_m))))
            for tau in ALLAN_TAUS_S:
                m = round(tau * FS_HZ)
                ad_m = allan_deviation([g], m)
                ad_s = float(np.mean([allan_deviation([x], m) for x in sims]))
                out.append(Score(f"{s} {a}: Allan dev. at {tau:g} s (°/s)", "held out", ad_m,
                                 ad_s, abs(math.log(ad_s / ad_m))))
            want = [f for f, _ in lines_in(g)]
            if want:
                found = [np.mean([any(abs(f - h) <= TOLERANCE_HZ for h, _ in lines_in(x))
                                  for x in sims]) for f in want]
                share = float(np.mean(found))
                out.append(Score(f"{s} {a}: share of {len(want)} line(s) reproduced",
                                 "held out", 1.0, share, 1.0 - share))
    return tuple(out)


def fit_bmi(data: Mapping[str, Mapping[str, FloatArray]]) -> dict[str, GyroParams]:
    """One gyro per plateau, fitted on the plateau's first half."""
    return {s: fit_session(_half(d, second=False)) for s, d in data.items()}
