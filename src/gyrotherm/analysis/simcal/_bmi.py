"""The simulator calibrated to the BMI270 plateaus, held out across sessions
(docs/findings.md §1, §7).

Data: ``bmi270_static_clean.csv`` of the BMI270 data set (© 2026 Ganesh Yerramsetti,
MIT; see its SOURCE.md): two isothermal plateaus (cold ≈ 13 °C, 65 s; hot ≈ 48 °C,
131 s), separate sessions, 50 Hz nominal, output quantum 1/16.4 °/s. Fitted on one
whole session and scored on the other (cold → hot, hot → cold), per axis:

* lines: in each band (0.1–2, 2–12, 12–25 Hz) the strongest Welch PSD bin
  (nperseg 512), kept if it is ≥ 4× the band's median; its amplitude A (°/s) by
  least squares of a sinusoid at that frequency, refined on a 0.002-Hz grid
  (±0.1 Hz) to the largest A;
* white level: σ_w² = var − Σ A²/2 − q²/12 (q the output quantum), N = σ_w·60/√f_s.

Scored on the other session's axis (simulated: isothermal plateaus of the same
length, quantised to q, one per seed): per seed e = |ln(sim/measured)| of the std and
of the Allan deviation at τ = 0.1, 1 s, and the share of the scored axis' lines
(same rule) the simulation does not show within ±0.5 Hz; the axis' error per seed
is the mean of these. Null comparisons (:mod:`._nulls`): the white level
against the default N and zero, the lines against none (white refitted to the whole
variance).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.signal import welch

from gyrotherm._errors import ConfigError
from gyrotherm.analysis._stats import allan_deviation
from gyrotherm.analysis.simcal._nulls import NullTest, run_null_tests
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
        median = float(np.median(p[sel]))
        prom = float(p[sel][i]) / median if median > 0 else 0.0  # 0: a constant signal
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


def fit_session(data: Mapping[str, FloatArray], *, white: Mapping[str, float] | None = None,
                lines_off: Collection[str] = ()) -> GyroParams:
    """Per-axis white level and lines of one plateau (module docstring); ``white``
    holds axes' levels (°/√h) fixed, ``lines_off`` fits no lines on those axes."""
    lines: list[SpectralLine] = []
    arw: dict[str, float] = {}
    for a in AXES:
        g = data[a]
        power = 0.0
        for f0, _ in ([] if a in lines_off else lines_in(g)):
            f, amp = sine_amplitude(g, f0)
            lines.append(SpectralLine(frequency_hz=f, amplitude_dps={a: amp}))
            power += amp**2 / 2
        level = math.sqrt(max(float(np.var(g)) - power - LSB_DPS**2 / 12, 0.0))
        arw[a] = (white or {}).get(a, level * 60 / math.sqrt(FS_HZ))
    base = GyroParams().quiet()
    return replace(base, rate_lsb_dps=LSB_DPS, arw_by_axis_deg_per_rth=arw,
                   lines=tuple(lines))


def line_rms(gyro: GyroParams, axis: str) -> float:
    """√(Σ A²/2) of ``gyro``'s lines on ``axis`` (°/s): their share of the std."""
    return math.sqrt(sum(ln.amplitude_dps.get(axis, 0.0) ** 2 / 2 for ln in gyro.lines))


def simulate_plateau(gyro: GyroParams, *, axis: str, n: int, temp_c: float,
                     seed: int) -> FloatArray:
    """n samples (50 Hz) of ``gyro``'s rate on ``axis`` at constant ``temp_c``, bias removed."""
    profile = ChamberProfile.from_pairs([(0.0, temp_c), (n / FS_HZ, temp_c)])
    still = ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0)
    run = simulate(profile, name="plateau", gyro=replace(gyro, axes=(axis,)), chamber=still,
                   rate_hz=FS_HZ, seed=seed)
    return np.asarray(run.rates_dps[axis][:n] - run.true_bias_dps[axis][:n], dtype=float)


def axis_errors(gyro: GyroParams, data: Mapping[str, FloatArray], axis: str, *,
                seeds: Sequence[int]) -> list[float]:
    """Per seed, the mean error of ``gyro``'s ``axis`` on the plateau ``data``."""
    g = data[axis]
    temp = float(np.mean(data["temp_c"]))
    want = [f for f, _ in lines_in(g)]
    out = []
    for k in seeds:
        x = simulate_plateau(gyro, axis=axis, n=len(g), temp_c=temp, seed=k)
        e = [abs(math.log(np.std(x) / np.std(g)))]
        for tau in ALLAN_TAUS_S:
            m = round(tau * FS_HZ)
            e.append(abs(math.log(allan_deviation([x], m) / allan_deviation([g], m))))
        if want:
            have = [h for h, _ in lines_in(x)]
            e.append(1.0 - float(np.mean([any(abs(f - h) <= TOLERANCE_HZ for h in have)
                                          for f in want])))
        out.append(float(np.mean(e)))
    return out


DIRECTIONS: tuple[tuple[str, str], ...] = (("cold", "hot"), ("hot", "cold"))


def cross_session_tests(data: Mapping[str, Mapping[str, FloatArray]], *,
                        seeds: Sequence[int]) -> dict[tuple[str, str], list[NullTest]]:
    """Per direction (fit session, scored session): the null test of each axis' white
    level ("white x", …; °/√h) and lines ("lines x", …; value: their RMS, °/s)."""
    out: dict[tuple[str, str], list[NullTest]] = {}
    default_white = GyroParams().arw_deg_per_rth
    for fit_s, score_s in DIRECTIONS:
        fitted = fit_session(data[fit_s])
        tests: list[NullTest] = []
        for a in AXES:
            def evaluate(name: str, value: float, a: str = a, fit_s: str = fit_s,
                         score_s: str = score_s) -> list[float]:
                gyro = (fit_session(data[fit_s], white={a: value}) if name.startswith("white")
                        else fit_session(data[fit_s], lines_off={a}))
                return axis_errors(gyro, data[score_s], a, seeds=seeds)

            values = {f"white {a}": fitted.arw_for(a), f"lines {a}": line_rms(fitted, a)}
            defaults = {f"white {a}": default_white, f"lines {a}": 0.0}
            errors = axis_errors(fitted, data[score_s], a, seeds=seeds)
            tests += run_null_tests({k: v for k, v in values.items()
                                     if not (k.startswith("lines") and v == 0)},
                                    defaults, (), dict.fromkeys(values, errors), evaluate)
        out[(fit_s, score_s)] = tests
    return out


def fit_bmi(data: Mapping[str, Mapping[str, FloatArray]]) -> dict[str, GyroParams]:
    """One gyro per plateau, fitted on the whole plateau (a description of it)."""
    return {s: fit_session(d) for s, d in data.items()}
