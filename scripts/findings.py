"""Regenerate docs/findings.md and its figures (docs/figures/findings/*.png) in one command.

    .venv/bin/python scripts/findings.py

Every number in docs/findings.md is computed here, from
../shared/data/measured (BMI270 plateaus, MIT licence, © 2026 Ganesh
Yerramsetti, github.com/Ganesh999-tech/BMI270-Thermal-Drift-Compensation), the
values printed in Tang et al. 2013 (Tables 1, 2, Fig. 6), gyrotherm's
simulator and the independent generator gyrotherm.analysis.synth_runs.
Seeded: the output is the same on every run.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import welch

from gyrotherm.analysis import (
    SynthConfig,
    allan_deviation,
    diagnose,
    synth_runs,
    write_report,
)
from gyrotherm.compensation import features, fit, fit_per_run, score
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import (
    DEFAULT_TRUE_BIAS,
    ChamberModel,
    ChamberProfile,
    GyroParams,
    chamber_runs,
    heating_profile,
    simulate,
)

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "measured" / "bmi270-peltier-laptop"
if not DATA.exists():
    DATA = Path("/work/shared/data/measured/bmi270-peltier-laptop")
FIG = ROOT / "docs" / "figures" / "findings"
OUT = ROOT / "docs" / "findings.md"
AXES = ("x", "y", "z")

# Tang et al. 2013, Table 1: a1..a5 per heating time (min); Table 2; Fig. 6.
TABLE1 = {
    5: (0.0000019504876, -0.23537397, -7.4260978, 0.00098190674, 10315.948),
    10: (0.000002676828, -0.24618153, -3.6553626, 0.00044286063, 10354.223),
    20: (0.0000041203692, -0.27028934, -10.03044, 0.0013282806, 10453.302),
    30: (0.0000038654453, -0.26552597, -5.6036385, 0.00076193292, 10430.86),
    40: (0.0000021652523, -0.23869247, 2.9620516, -0.00037816028, 10326.501),
    50: (0.0000024462827, -0.24380525, -3.1428874, 0.00039041132, 10347.9),
    60: (0.0000040797022, -0.26828756, -9.0600264, 0.001377608, 10439.366),
}
TABLE2 = {"t2 5 min": (-0.0357, 0.0598), "t2 50 min": (0.0321, 0.0512),
          "t2 60 min": (-0.0079, 0.0482), "paper (eq. 12)": (0.0014, 0.0430)}
FIG6 = {30: (2.36, 0.84), 60: (1.17, 0.57)}


def fmt(v: float, digits: int = 3) -> str:
    if not math.isfinite(v):
        return "—"
    return f"{v:.{digits}g}"


# --------------------------------------------------------------------- BMI270 --

FS_HZ = 50.0  # nominal (SOURCE.md: no timestamps)
LSB_DPS = 1 / 16.4
ALLAN_TAUS_S = (0.1, 1.0, 10.0)
PSD_BANDS_HZ = ((0.1, 2.0), (2.0, 12.0), (12.0, 25.0))
LINE_PROMINENCE = 4.0  # peak PSD / median PSD of its band
LINE_TOLERANCE_HZ = 0.5  # same line in both halves


def white_allan_band(n: int, ms: list[int], seed: int, reps: int = 200) -> dict[int, tuple[
        float, float]]:
    """5–95 % range of σ_A(m)/(σ/√m) for Gaussian white noise of n samples."""
    rng = np.random.default_rng(seed)
    r = np.empty((reps, len(ms)))
    for i in range(reps):
        w = rng.standard_normal(n)
        sd = float(np.std(w))
        r[i] = [allan_deviation([w], m) / (sd / math.sqrt(m)) for m in ms]
    lo, hi = np.percentile(r, [5, 95], axis=0)
    return {m: (float(lo[j]), float(hi[j])) for j, m in enumerate(ms)}


def spectral_line(x: np.ndarray, band: tuple[float, float]) -> tuple[float, float]:
    """Frequency (Hz) of the PSD maximum in ``band`` and its height over the band's median."""
    f, p = welch(x - x.mean(), fs=FS_HZ, nperseg=512)
    sel = (f >= band[0]) & (f < band[1])
    i = int(np.argmax(p[sel]))
    return float(f[sel][i]), float(p[sel][i] / np.median(p[sel]))


def robust_line(g: np.ndarray, band: tuple[float, float]) -> tuple[float, float] | None:
    """The band's strongest line if it stands out, at one frequency, in the whole run and
    in each half; else None."""
    half = len(g) // 2
    found = [spectral_line(x, band) for x in (g, g[:half], g[half:])]
    f0 = found[0][0]
    if all(prom >= LINE_PROMINENCE and abs(f - f0) <= LINE_TOLERANCE_HZ for f, prom in found):
        return found[0]
    return None


def sim_std(sigma_dps: float, n: int, temp_c: float, axis: str, seeds: range) -> float:
    """Std (°/s) of gyrotherm's simulator on an isothermal plateau of n samples at 50 Hz, with
    white noise set so that the quantised output has std ``sigma_dps`` (mean over seeds)."""
    white = math.sqrt(max(sigma_dps**2 - LSB_DPS**2 / 12, 0.0))
    gyro = replace(GyroParams().quiet(), arw_deg_per_rth=white * 60 / math.sqrt(FS_HZ),
                   rate_lsb_dps=LSB_DPS, axes=(axis,))
    profile = ChamberProfile.from_pairs([(0.0, temp_c), (n / FS_HZ, temp_c)])
    still = ChamberModel(lag_s=0.0, bow_c=0.0, noise_c=0.0)
    out = [float(np.std(simulate(profile, name="plateau", gyro=gyro, chamber=still,
                                 rate_hz=FS_HZ, seed=seed).rates_dps[axis][:n]))
           for seed in seeds]
    return float(np.mean(out))


def bmi270_noise_models(seg: dict[str, np.ndarray], nums: dict[str, float]) -> list[str]:
    """gyrotherm's simulator with white-noise levels fitted on the first half of each plateau,
    scored on the second half (out of sample)."""
    seeds = range(1, 6)
    sig1 = {(s, a): float(np.std(d[f"gyro_{a}_dps"][: len(d) // 2].astype(float)))
            for s, d in seg.items() for a in AXES}
    sig2 = {(s, a): float(np.std(d[f"gyro_{a}_dps"][len(d) // 2:].astype(float)))
            for s, d in seg.items() for a in AXES}
    n1 = {s: len(d) // 2 for s, d in seg.items()}
    n2 = {s: len(d) - len(d) // 2 for s, d in seg.items()}
    temp = {s: float(np.mean(d["temp_degC"])) for s, d in seg.items()}
    env = {a: math.sqrt(max(sig1[("hot", a)] ** 2 - sig1[("cold", a)] ** 2, 0.0)) for a in AXES}
    lines = ["| axis | measured hot/cold std, 2nd halves | simulated hot/cold: one ARW | "
             "one ARW per run | shared environment term | worst plateau std error: one ARW | "
             "one ARW per run | shared environment term | measured hot std, 1st → 2nd half |",
             "|---|---|---|---|---|---|---|---|---|"]
    for a in AXES:
        pooled = math.sqrt(sum(n1[s] * sig1[(s, a)] ** 2 for s in seg) / sum(n1.values()))
        others = [b for b in AXES if b != a]
        shared = math.sqrt(sum(env[b] ** 2 for b in others) / len(others))
        level = {
            "one": {s: pooled for s in seg},
            "run": {s: sig1[(s, a)] for s in seg},  # = device (cold) level + environment term
            "shared": {"cold": sig1[("cold", a)],
                       "hot": math.hypot(sig1[("cold", a)], shared)},
        }
        row = [a, fmt(sig2[("hot", a)] / sig2[("cold", a)])]
        errs = []
        for key, lv in level.items():
            sim = {s: sim_std(lv[s], n2[s], temp[s], a, seeds) for s in seg}
            row.append(fmt(sim["hot"] / sim["cold"]))
            err = max(abs(sim[s] / sig2[(s, a)] - 1) for s in seg)
            nums[f"err_{key}_{a}"] = err
            errs.append(f"{100 * err:.0f} %")
        change = sig2[("hot", a)] / sig1[("hot", a)] - 1
        nums[f"hot_{a}_half_change"] = change
        nums[f"hot_{a}_h1"] = sig1[("hot", a)]
        nums[f"hot_{a}_h2"] = sig2[("hot", a)]
        nums[f"env_{a}"] = env[a]
        lines.append("| " + " | ".join(row + errs) + f" | {100 * change:+.0f} % |")
    return lines


def bmi270() -> tuple[list[str], dict[str, float], dict[str, str]]:
    raw = np.genfromtxt(DATA / "bmi270_static_clean.csv", delimiter=",", names=True,
                        dtype=None, encoding="utf-8")
    fs = FS_HZ
    seg = {s: raw[raw["segment"] == s] for s in ("cold", "hot")}
    rows = []
    nums: dict[str, float] = {}
    text: dict[str, str] = {}
    adev_curves = {}
    bands = {}
    psd = {}
    allan_rows = []
    line_rows = []
    excess: dict[str, list[str]] = {}  # plateau-axes outside white noise's range, per τ
    for k, (s, d) in enumerate(seg.items()):
        temp = float(np.mean(d["temp_degC"]))
        n = len(d)
        nums[f"{s}_duration_s"] = n / fs
        nums[f"{s}_temp_c"] = temp
        taus = [int(m) for m in np.unique(np.geomspace(1, n // 4, 20).astype(int))]
        table_ms = [round(t * fs) for t in ALLAN_TAUS_S]
        band = white_allan_band(n, sorted({*taus, *table_ms}), seed=11 + k)
        bands[s] = (np.array(taus) / fs, np.array([band[m] for m in taus]))
        allan_rows.append(f"| {s} | white noise, {n} samples: 5–95 % range | "
                          + " | ".join(f"{band[m][0]:.2f}–{band[m][1]:.2f}" for m in table_ms)
                          + " |")
        for a in AXES:
            g = d[f"gyro_{a}_dps"].astype(float)
            std = float(np.std(g))
            white = float(np.std(np.diff(g)) / math.sqrt(2))
            arw = white * 60 / math.sqrt(fs)
            acc = d[f"acc_{a}"].astype(float) * 4.0 * 1000  # mg (SOURCE.md: value is g/4)
            acc_std = float(np.std(acc))
            blocks = acc[: n // 50 * 50].reshape(-1, 50)  # 1-s blocks
            acc_1s = float(np.sqrt(np.mean(blocks.var(axis=1))))
            adev_curves[(s, a)] = (np.array(taus) / fs, [allan_deviation([g], m) for m in taus])
            f, p = welch(g - g.mean(), fs=fs, nperseg=512)
            psd[(s, a)] = (f, p)
            nums[f"{s}_{a}_std"] = std
            nums[f"{s}_{a}_acc_mg"] = acc_std
            nums[f"{s}_{a}_acc1s_mg"] = acc_1s
            nums[f"{s}_{a}_acc_first10_mg"] = float(acc[:500].mean())
            nums[f"{s}_{a}_acc_last10_mg"] = float(acc[-500:].mean())
            nums[f"{s}_{a}_acc_quantum_mg"] = float(np.min(np.diff(np.unique(acc))))
            lo = p[(f > 0.5) & (f < 5)].mean()
            hi = p[f > 15].mean()
            rows.append((s, temp, a, std, white, arw, acc_std, acc_1s, float(hi / lo)))
            cells = []
            for tau, m in zip(ALLAN_TAUS_S, table_ms, strict=True):
                r = allan_deviation([g], m) / (std / math.sqrt(m))
                nums[f"{s}_{a}_adev_{tau:g}"] = r
                outside = r < band[m][0] or r > band[m][1]
                cells.append(f"**{r:.2f}**" if outside else f"{r:.2f}")
                if outside:
                    side = "low" if r < band[m][0] else "high"
                    excess.setdefault(f"adev_{side}_{tau:g}", []).append(f"{s} {a} {r:.2f}×")
            allan_rows.append(f"| {s} | {a} | " + " | ".join(cells) + " |")
            lcells = []
            for b in PSD_BANDS_HZ:
                line = robust_line(g, b)
                if line is None:
                    lcells.append("—")
                else:
                    lcells.append(f"{line[0]:.2f} Hz (×{line[1]:.0f})")
                    nums[f"{s}_{a}_line_{b[0]:g}"] = line[0]
            line_rows.append(f"| {s} | {a} | " + " | ".join(lcells) + " |")
    text |= {k: ", ".join(v) for k, v in excess.items()}
    # robust lines, per plateau and band: "0.39 Hz (x, y)"
    for s in seg:
        parts = []
        for b in PSD_BANDS_HZ:
            hits = [(a, nums[f"{s}_{a}_line_{b[0]:g}"]) for a in AXES
                    if f"{s}_{a}_line_{b[0]:g}" in nums]
            if hits:
                fr = [h[1] for h in hits]
                span = f"{min(fr):.2f}" if max(fr) - min(fr) < 0.05 else \
                    f"{min(fr):.2f}–{max(fr):.2f}"
                parts.append(f"{span} Hz ({', '.join(h[0] for h in hits)})")
        text[f"lines_{s}"] = "; ".join(parts) if parts else "none"
    freqs = {s: [v for k, v in nums.items() if k.startswith(f"{s}_") and "_line_" in k]
             for s in seg}
    shared = sorted({f"{fc:.2f}" for fc in freqs["cold"] for fh in freqs["hot"]
                     if abs(fc - fh) <= LINE_TOLERANCE_HZ})
    text["lines_shared"] = ("The two sessions share none of them." if not shared else
                            f"Lines within ±{LINE_TOLERANCE_HZ:g} Hz in both sessions: "
                            f"{', '.join(shared)} Hz.")
    ratios = bmi270_noise_models(seg, nums)
    # figures
    fig, axs = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, a in zip(axs, AXES, strict=True):
        for s, c in (("cold", "tab:blue"), ("hot", "tab:red")):
            x, y = adev_curves[(s, a)]
            ax.loglog(x, y, color=c, label=f"{s} ({np.mean(seg[s]['temp_degC']):.1f} °C)")
            white_line = nums[f"{s}_{a}_std"] / np.sqrt(x * fs)
            ax.loglog(x, white_line, color=c, ls=":", lw=0.8)
            bx, bb = bands[s]
            ax.fill_between(bx, white_line * bb[:, 0], white_line * bb[:, 1], color=c,
                            alpha=0.12, lw=0)
        ax.set_title(f"gyro {a}")
        ax.set_xlabel("τ (s)")
        ax.grid(True, which="both", lw=0.3)
    axs[0].set_ylabel("Allan deviation (°/s)")
    axs[0].legend(fontsize=8)
    fig.suptitle("BMI270 static plateaus (data: Ganesh Yerramsetti, MIT); dotted: white noise "
                 "of the same std, shaded: its 5–95 % range for the record length")
    fig.tight_layout()
    fig.savefig(FIG / "bmi270_allan.png", dpi=110)
    plt.close(fig)
    fig, axs = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, a in zip(axs, AXES, strict=True):
        for s, c in (("cold", "tab:blue"), ("hot", "tab:red")):
            f, p = psd[(s, a)]
            ax.semilogy(f, p, color=c, label=s)
        ax.set_title(f"gyro {a}")
        ax.set_xlabel("frequency (Hz; nominal 50 Hz sampling, aliased above 25 Hz)")
    axs[0].set_ylabel("PSD ((°/s)²/Hz)")
    axs[0].legend()
    fig.tight_layout()
    fig.savefig(FIG / "bmi270_psd.png", dpi=110)
    plt.close(fig)
    table = ["| plateau | T (°C) | axis | std (°/s) | Allan dev. at 0.02 s (°/s) | "
             "ARW from 0.02 s (°/√h) | accel std (mg) | accel std within 1 s (mg) | "
             "PSD >15 Hz / 0.5–5 Hz |", "|---|---|---|---|---|---|---|---|---|"]
    table += [f"| {s} | {t:.2f} | {a} | {std:.3f} | {w:.3f} | {arw:.2f} | {acc:.1f} | "
              f"{acc1:.1f} | {r:.2f} |"
              for s, t, a, std, w, arw, acc, acc1, r in rows]
    allan = ["| plateau | axis | "
             + " | ".join(f"σ_A / (σ/√m) at τ = {t:g} s" for t in ALLAN_TAUS_S) + " |",
             "|---|---|---|---|---|", *allan_rows]
    lines_t = ["| plateau | axis | "
               + " | ".join(f"line in {lo:g}–{hi:g} Hz" for lo, hi in PSD_BANDS_HZ) + " |",
               "|---|---|---|---|---|", *line_rows]
    # the diagnosis refuses these runs: no temperature change within either plateau
    from gyrotherm.codecs import Run

    runs = [Run(name=s, time_s=d["t_nominal_s"].astype(float),
                temperature_c=d["temp_degC"].astype(float),
                rates_dps={a: d[f"gyro_{a}_dps"].astype(float) for a in AXES})
            for s, d in seg.items()]
    try:
        diagnose(runs, simulate=False)
        refusal = "(unexpectedly accepted)"
    except Exception as exc:  # the message is part of the finding
        refusal = str(exc)
    text["refusal"] = refusal
    return [*table], nums, text | {"allan": "\n".join(allan), "lines": "\n".join(lines_t),
                                   "ratios": "\n".join(ratios)}


# --------------------------------------------------------------- Tang Table 1 --

T_MID_C = 15.0  # middle of the paper's −20…50 °C, where the simulator's ΔT coefficient is read


def table1_structure() -> tuple[list[str], dict[str, float]]:
    a = np.array(list(TABLE1.values()))
    nums: dict[str, float] = {}
    names = ["a1", "a2", "a3", "a4", "a5"]
    cv = np.std(a, axis=0, ddof=1) / np.abs(np.mean(a, axis=0))
    for i, n in enumerate(names):
        nums[f"cv_{n}"] = float(cv[i])
    nums["corr_a3_a4"] = float(np.corrcoef(a[:, 2], a[:, 3])[0, 1])
    nums["corr_a2_a5"] = float(np.corrcoef(a[:, 1], a[:, 4])[0, 1])
    nums["corr_a1_a2"] = float(np.corrcoef(a[:, 0], a[:, 1])[0, 1])
    # a3 + a4·T* is what the data fix; T* from the a3-on-a4 regression (the T where it
    # spreads least)
    slope, _icpt = np.polyfit(a[:, 3], a[:, 2], 1)
    t_star = -slope
    comb = a[:, 2] + a[:, 3] * t_star
    nums["t_star"] = float(t_star)
    nums["comb_mean"] = float(comb.mean())
    nums["comb_std"] = float(comb.std(ddof=1))
    nums["comb_cv"] = float(comb.std(ddof=1) / abs(comb.mean()))
    nums["comb_sem"] = float(comb.std(ddof=1) / math.sqrt(len(comb)))
    nums["a3_std"] = float(a[:, 2].std(ddof=1))
    # the T where a2 + 2·a1·T spreads least: the a2-on-a1 regression has slope −2T
    slope12, _ = np.polyfit(a[:, 0], a[:, 1], 1)
    nums["t_star_12"] = float(-slope12 / 2)
    # the well-determined temperature slope at T*: a2 + 2 a1 T*
    slope_t = a[:, 1] + 2 * a[:, 0] * t_star
    nums["slope_t_cv"] = float(slope_t.std(ddof=1) / abs(slope_t.mean()))
    nums["comb_per_slope"] = float(comb.std(ddof=1) / abs(slope_t.mean()))
    nums["comb_mean_per_slope"] = float(abs(comb.mean()) / abs(slope_t.mean()))
    nums["sem_per_slope"] = float(nums["comb_sem"] / abs(slope_t.mean()))
    return [], nums


def sim_table1(label: str, gyro: GyroParams, chamber: ChamberModel, seeds: range) -> dict[
    str, float | str
]:
    """Per-run paper-model fits of simulated chamber runs: the ΔT coefficient a3 + a4·T at
    T = T_MID_C (°C), its spread, and corr(a3, a4); means over seeds."""
    est = EstimatorConfig(tau_s=gyro.tau_s, update_period_s=1.0)
    means, stds, cvs, per_slope, mean_per_slope, corr = [], [], [], [], [], []
    for seed in seeds:
        runs = chamber_runs(seed=seed, rate_hz=1.0, gyro=gyro, chamber=chamber)
        feats = [features(r, est) for r in runs]
        per = fit_per_run(feats, "paper", estimator=est)
        phys = np.array([[c.physical_coefficients("x")[t] for t in ("T^2", "T", "dT", "T*dT", "1")]
                         for c in per])
        comb = phys[:, 2] + phys[:, 3] * T_MID_C
        slope_t = phys[:, 1] + 2 * phys[:, 0] * T_MID_C
        means.append(float(comb.mean()))
        stds.append(float(comb.std(ddof=1)))
        cvs.append(float(comb.std(ddof=1) / abs(comb.mean())))
        per_slope.append(float(comb.std(ddof=1) / abs(slope_t.mean())))
        mean_per_slope.append(float(abs(comb.mean()) / abs(slope_t.mean())))
        corr.append(float(np.corrcoef(phys[:, 2], phys[:, 3])[0, 1]))
    return {"label": label, "mean": float(np.mean(means)), "std": float(np.mean(stds)),
            "cv": float(np.mean(cvs)), "per_slope": float(np.mean(per_slope)),
            "mean_per_slope": float(np.mean(mean_per_slope)),
            "corr_a3_a4": float(np.mean(corr))}


def table1(quick: bool = False) -> tuple[list[str], dict[str, float]]:
    _, nums = table1_structure()
    seeds = range(1, 3 if quick else 4)
    base = GyroParams()
    configs = [
        ("white noise only (one set of coefficients)",
         replace(base.quiet(), arw_deg_per_rth=base.arw_deg_per_rth),
         ChamberModel(bow_c=0.0, noise_c=0.0)),
        ("simulator defaults (ARW, BI 20 °/h, RRW, offsets, chamber bow + noise)", base,
         ChamberModel()),
        ("+ strong correlated bias noise (BI 150 °/h, τ 600 s)",
         replace(base, bias_instability_deg_per_h=150.0, bi_tau_s=600.0), ChamberModel()),
    ]
    results = [sim_table1(label, g, c, seeds) for label, g, c in configs]
    lines = ["| source | T | a3 + a4·T: mean ± std | CV = std / abs(mean) | "
             "std / abs(a2 + 2·a1·T) | corr(a3, a4) |", "|---|---|---|---|---|---|",
             f"| Tang et al. Table 1 (measured, raw units) | T* = {nums['t_star']:.0f} (raw) | "
             f"{nums['comb_mean']:.3f} ± {nums['comb_std']:.3f} | {nums['comb_cv']:.2f} | "
             f"{nums['comb_per_slope']:.2f} | {nums['corr_a3_a4']:.4f} |"]
    for r in results:
        lines.append(f"| simulated, axis x (°/s, °C): {r['label']} | {T_MID_C:g} °C | "
                     f"{float(r['mean']):.4f} ± {float(r['std']):.4f} | {float(r['cv']):.3f} | "
                     f"{float(r['per_slope']):.2f} | {float(r['corr_a3_a4']):.3f} |")
    for i, r in enumerate(results):
        for k in ("mean", "std", "cv", "per_slope", "mean_per_slope", "corr_a3_a4"):
            nums[f"sim{i}_{k}"] = float(r[k])
    return lines, nums


def table2_fig6() -> tuple[list[str], dict[str, float]]:
    nums: dict[str, float] = {}
    gyro = GyroParams()
    est = EstimatorConfig(tau_s=gyro.tau_s, update_period_s=1.0)
    runs = chamber_runs(seed=1, rate_hz=1.0)
    valid = chamber_runs([60], seed=1, rate_hz=1.0, validation=True)[0]
    feats = [features(r, est) for r in runs]
    vf = features(valid, est)
    avg = fit(feats, "paper", estimator=est, method="paper-average")
    cols = {"t2 5 min": fit([feats[0]], "t2", estimator=est),
            "t2 50 min": fit([feats[5]], "t2", estimator=est),
            "t2 60 min": fit([feats[6]], "t2", estimator=est),
            "paper (eq. 12)": avg}
    lines = ["| model | measured mean / RMS (°/s) | simulated mean / RMS, axis x (°/s) |",
             "|---|---|---|"]
    for name, cal in cols.items():
        s = score(cal, vf)[0].compensated
        m_mean, m_rms = TABLE2[name]
        lines.append(f"| {name} | {m_mean:+.4f} / {m_rms:.4f} | {s.mean_dps:+.4f} / "
                     f"{s.rms_dps:.4f} |")
        nums[f"t2_{name}"] = s.rms_dps
    # Fig. 6: ramp slope and residual std of the realised chamber air
    rng = np.random.default_rng(5)
    fig6 = ["| ramp | measured slope / residual std | simulated slope / residual std |",
            "|---|---|---|"]
    for minutes, (slope_m, res_m) in FIG6.items():
        prof = heating_profile(minutes)
        t = np.arange(0, prof.duration_s, 1.0)
        air = prof.realise(t, ChamberModel(), rng)
        on = (t >= 3600) & (t <= 3600 + minutes * 60)
        p = np.polyfit(t[on] / 60, air[on], 1)
        res = float(np.std(air[on] - np.polyval(p, t[on] / 60)))
        fig6.append(f"| {minutes} min | {slope_m:.2f} °C/min / {res_m:.2f} °C | "
                    f"{p[0]:.2f} °C/min / {res:.2f} °C |")
        nums[f"fig6_{minutes}_res"] = res
    return [*lines, "", *fig6], nums


# ------------------------------------------------------------ synthetic demo --

def synthetic_demo() -> tuple[list[str], dict[str, float]]:
    cfg = SynthConfig(duration_s=7200.0, effects={"hysteresis": {}, "drift": {}})
    runs, truth = synth_runs(cfg, n_runs=6, seed=28)
    start = time.perf_counter()
    d = diagnose(runs, seed=1)
    elapsed = time.perf_counter() - start
    write_report(d, FIG / "synthetic-report")
    nums = {"demo_gain": d.gain, "demo_s": elapsed}
    lines = ["| effect | injected | found |", "|---|---|---|"]
    found = {f.effect: f.params for f in d.findings}
    for name, params in truth.effects.items():
        got = found.get(name, {})
        lines.append(f"| {name} | " + ", ".join(f"{k} = {v:.4g}" for k, v in params.items())
                     + " | " + (", ".join(f"{k} = {v:.4g}" for k, v in got.items()) or "—")
                     + " |")
    for name in found:
        if name not in truth.effects:
            lines.append(f"| {name} | — | " + ", ".join(f"{k} = {v:.4g}" for k, v in
                                                       found[name].items()) + " |")
    lines += ["", f"Held-out RMS {d.baseline_heldout_rms_dps:.4f} → "
              f"{d.extended_heldout_rms_dps:.4f} °/s (gain {d.gain:.2f}).", "",
              "| statistic | measured | simulated (paper) | simulated (extended) |",
              "|---|---|---|---|"]
    assert d.simulation is not None
    for m in d.simulation.mismatch[:6]:
        ext = m.simulated_extended if m.simulated_extended is not None else math.nan
        lines.append(f"| {m.statistic} | {fmt(m.measured)} | {fmt(m.simulated)} | {fmt(ext)} |")
    return lines, nums




def _times(values: list[float]) -> str:
    return ", ".join(f"×{v:.2f}" for v in values)


def accel_sentence(b: dict[str, float]) -> str:
    """What the accelerometer does on the hot plateau, per axis, from the computed stds."""
    gyro = {a: b[f"hot_{a}_std"] / b[f"cold_{a}_std"] for a in AXES}
    total = {a: b[f"hot_{a}_acc_mg"] / b[f"cold_{a}_acc_mg"] for a in AXES}
    within = {a: b[f"hot_{a}_acc1s_mg"] / b[f"cold_{a}_acc1s_mg"] for a in AXES}
    up = [a for a in AXES if total[a] > 1]
    down = [a for a in AXES if total[a] <= 1]
    lower = [a for a in AXES if within[a] < 1]
    out = ("Its std within 1-s blocks (vibration above ≈ 1 Hz) is lower on the hot plateau on "
           f"{'every axis' if len(lower) == len(AXES) else ', '.join(lower) or 'no axis'} "
           f"({_times([within[a] for a in AXES])} on x, y, z).")
    if down:
        out += (f" Its whole-plateau std falls on {', '.join(down)} "
                f"({_times([total[a] for a in down])}).")
    for a in up:
        out += (f" On {a} it rises ×{total[a]:.2f} ({b[f'cold_{a}_acc_mg']:.1f} → "
                f"{b[f'hot_{a}_acc_mg']:.1f} mg; the gyro's std on {a} rises ×{gyro[a]:.2f}), "
                f"but its 1-s means drift from {b[f'hot_{a}_acc_first10_mg']:.1f} to "
                f"{b[f'hot_{a}_acc_last10_mg']:.1f} mg between the first and the last 10 s: "
                "a slow change, not vibration.")
    return out


def main() -> None:
    FIG.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    bmi_lines, b, bt = bmi270()
    t1_lines, t1 = table1()
    t2_lines, t2 = table2_fig6()
    demo_lines, demo = synthetic_demo()
    gyro_ratio = {a: b[f"hot_{a}_std"] / b[f"cold_{a}_std"] for a in AXES}
    n_low_short = len(bt.get("adev_low_0.1", "").split(", ")) if "adev_low_0.1" in bt else 0
    hot_line = b.get("hot_x_line_0.1", math.nan)
    worst = {k: max(AXES, key=lambda a: b[f"err_{k}_{a}"]) for k in ("one", "run", "shared")}
    halves = max(AXES, key=lambda a: abs(b[f"hot_{a}_half_change"]))
    true_dt = DEFAULT_TRUE_BIAS["x"]["dT"] + DEFAULT_TRUE_BIAS["x"]["T*dT"] * T_MID_C
    cv_gap = [t1["comb_cv"] / t1[f"sim{i}_cv"] for i in range(3)]
    doc = [
        "# Findings: what the model and the simulator miss",
        "",
        "Every number and figure here is produced by `scripts/findings.py` "
        "(`.venv/bin/python scripts/findings.py`, seeded, "
        f"{time.perf_counter() - start:.0f} s on this machine); edit the script, not this file.",
        "",
        "Data: the BMI270 plateaus in `../shared/data/measured/bmi270-peltier-laptop/` "
        "(Bosch BMI270, © 2026 Ganesh Yerramsetti, MIT licence, "
        "github.com/Ganesh999-tech/BMI270-Thermal-Drift-Compensation; see its SOURCE.md), "
        "and the values printed in Tang et al. 2013 (Table 1, Table 2, Fig. 6).",
        "",
        "## 1. BMI270: two isothermal plateaus",
        "",
        f"Two runs (cold ≈ {b['cold_temp_c']:.1f} °C on a Peltier module, "
        f"{b['cold_duration_s']:.0f} s; hot ≈ {b['hot_temp_c']:.1f} °C in a laptop's exhaust, "
        f"{b['hot_duration_s']:.0f} s), 50 Hz nominal (no timestamps), output quantum "
        f"{LSB_DPS:.3f} °/s.",
        "",
        *bmi_lines,
        "",
        "**What the simulation gets wrong.** gyrotherm's simulator (`GyroParams`) has one "
        "white-noise level (ARW) per device, the same on every axis and in every run. "
        f"Measured, the hot plateau is noisier: {_times([gyro_ratio[a] for a in AXES])} on "
        "x, y, z (std over the whole plateau).",
        "",
        "**The noise is not white.** The table gives the Allan deviation σ_A at averaging "
        "time τ over the white-noise value σ/√m of the same std σ (m = τ·50 Hz; the dotted "
        "lines in `bmi270_allan.png`); **bold**: outside the 5–95 % range of Gaussian white "
        "noise of the same length (shaded in the figure).",
        "",
        bt["allan"],
        "",
        f"At τ = 0.1 s the Allan deviation is below white on {n_low_short} of 6 plateau-axes "
        f"({bt.get('adev_low_0.1', 'none')}): part of the variance sits in narrow spectral "
        "lines and, on the hot plateau, above 15 Hz (PSD ratio column in the first table), "
        "and averages out faster than white noise. At τ = 1 s it is above white on "
        f"{bt.get('adev_high_1', 'none')} and below on {bt.get('adev_low_1', 'none')}; at "
        f"τ = 10 s above on {bt.get('adev_high_10', 'none')} and below on "
        f"{bt.get('adev_low_10', 'none')}. Hot x's excess at 1 s fits its "
        f"{hot_line:.2f} Hz line (below): a sinusoid of frequency f₀ peaks in Allan "
        f"deviation at τ ≈ 0.371/f₀ = {0.371 / hot_line:.2f} s (IEEE Std 952-1997). "
        "So no white-noise level describes either plateau; a per-run white level can match "
        "the std, not the spectrum.",
        "",
        "Spectral lines: the strongest PSD bin of each band, listed if it is at least "
        f"{LINE_PROMINENCE:g}× the band's median PSD in the whole plateau and in each half, "
        f"at the same frequency (±{LINE_TOLERANCE_HZ:g} Hz). Frequencies assume the nominal "
        "50 Hz; anything above 25 Hz is aliased into 0–25 Hz.",
        "",
        bt["lines"],
        "",
        f"The cold plateau has lines at {bt['lines_cold']}; the hot plateau at "
        f"{bt['lines_hot']}. {bt['lines_shared']}",
        "",
        "**Cause: not established by these data.** Each temperature is one session, with "
        "its own heat source (a Peltier module; a laptop's exhaust), orientation (−Z vs +X "
        "up, which can shift the bias through g-sensitivity) and power-on, so temperature "
        "cannot be separated from the session. Session-specific lines are consistent with an "
        "environmental source (the laptop's exhaust fan is one candidate), but the "
        "accelerometer does not show a vibration. "
        + accel_sentence(b)
        + " So the accelerometer gives no support for translational vibration in the hot "
        "session; it cannot rule out rotational jitter, to which an accelerometer is nearly "
        f"insensitive. Its output quantum in these logs is {b['hot_z_acc_quantum_mg']:.0f} mg "
        "(0.001 in the g/4 units of SOURCE.md).",
        "",
        "**What gyrotherm's simulator does with a per-run noise level, out of sample.** "
        "White-noise levels are fitted on the first half of each plateau; "
        "`gyrotherm.sim.simulate` runs an isothermal plateau of the second half's length "
        "(one call per axis, `GyroParams.arw_deg_per_rth` set so that the output, quantised "
        f"to {LSB_DPS:.3f} °/s, has the fitted std; mean of 5 seeds), and its std is "
        "scored against the second half's. Three settings: one ARW per axis pooled over both "
        "runs (the simulator as calibrated to a device); one ARW per axis and run "
        "(equivalently the cold level plus an environment term σ_env = √(σ_hot² − σ_cold²) "
        "on the hot run: a per-run setting, not a function of T); and one environment term "
        "shared by the axes, fitted on the other two axes.",
        "",
        bt["ratios"],
        "",
        "The worst per-plateau error is "
        f"{100 * b['err_one_' + worst['one']]:.0f} % ({worst['one']}) with one ARW, "
        f"{100 * b['err_run_' + worst['run']]:.0f} % ({worst['run']}) with one ARW per run, "
        f"{100 * b['err_shared_' + worst['shared']]:.0f} % ({worst['shared']}) with a shared "
        "environment term: σ_env differs between axes ("
        + ", ".join(f"{b['env_' + a]:.2f}" for a in AXES)
        + " °/s on x, y, z, first halves). What the per-run level misses is the hot noise's "
        f"own change between halves ({100 * b['hot_' + halves + '_half_change']:+.0f} % on "
        f"{halves}: {b['hot_' + halves + '_h1']:.3f} → {b['hot_' + halves + '_h2']:.3f} °/s): "
        f"the hot noise level itself changes within the {b['hot_duration_s']:.0f}-s run.",
        "",
        f"`gyrotherm diagnose` on the two plateaus: *{bt['refusal']}*",
        "",
        "**What the diagnosis can and cannot say.** With one offset per run and no "
        "temperature change inside either plateau, no temperature model is identifiable "
        "from within-run variation, and `gyrotherm diagnose` says so (message above). "
        "Across plateaus the two-point slope is the SOURCE's +0.0191/+0.0129/−0.0015 °/s/°C; "
        "it cannot separate bias from g-sensitivity (orientation changed) or from a "
        "switch-on offset (each plateau is one power-on).",
        "",
        "![Allan deviation](figures/findings/bmi270_allan.png)",
        "![PSD](figures/findings/bmi270_psd.png)",
        "",
        "## 2. Tang et al. Table 1: the spread of coefficients across heating times",
        "",
        f"Table 1's coefficients vary strongly: CV of a3 = {t1['cv_a3']:.2f} (a3 even "
        f"changes sign), a4 {t1['cv_a4']:.2f}, a2 {t1['cv_a2']:.3f}, a5 {t1['cv_a5']:.4f}. "
        f"But they vary together: corr(a3, a4) = {t1['corr_a3_a4']:.4f}, "
        f"corr(a2, a5) = {t1['corr_a2_a5']:.4f}, corr(a1, a2) = {t1['corr_a1_a2']:.4f}. "
        "The regression of a3 on a4 has slope −T* with "
        f"T* = {t1['t_star']:.0f} (temperature in the paper's raw sensor units, far from 0), "
        "the temperature at which a3 + a4·T spreads least: "
        f"± {t1['comb_std']:.3f} (mean {t1['comb_mean']:.3f}), while a3 "
        f"alone spreads by ± {t1['a3_std']:.2f}, {t1['a3_std'] / t1['comb_std']:.0f}× more. "
        "The regression of a2 on a1 puts the best-determined temperature slope, "
        f"a2 + 2·a1·T, at T = {t1['t_star_12']:.0f}, close by. "
        "The data pin the gradient coefficient near T*; the uncentred fit splits it between "
        "a3 and a4 along an ill-conditioned direction. Likewise the temperature slope at "
        f"T*, a2 + 2·a1·T*, has CV {t1['slope_t_cv']:.3f} against a2's {t1['cv_a2']:.3f}. "
        "Most of Table 1's spread is parametrisation, which gyrotherm avoids by fitting in "
        "centred, scaled variables. What remains is large next to its mean: a3 + a4·T* "
        f"spreads by {t1['comb_cv']:.1f}× its mean, and the mean is "
        f"{abs(t1['comb_mean']) / t1['comb_sem']:.2f} standard errors from zero (standard "
        f"error {t1['comb_std']:.3f}/√7 = {t1['comb_sem']:.3f}).",
        "",
        "Is that remaining spread what noise in the runs produces? Simulated per-run fits "
        "(7 heating times, −20 → 50 °C, per-run paper-model fits, physical coefficients, "
        "axis x, mean over 3 seeds), compared on the same quantity: the ΔT coefficient at a "
        f"temperature inside the runs, a3 + a4·T, with T = {T_MID_C:g} °C (the middle of "
        "−20…50 °C) for the simulator and T = T* for the paper (whose temperature scale is "
        "unknown). Two scale-free measures: the CV, and the std in units of the temperature "
        "slope at the same T, std(a3 + a4·T) / abs(mean(a2 + 2·a1·T)), which assumes the "
        "paper's ΔT is in the same units as its T.",
        "",
        *t1_lines,
        "",
        "**What the simulation gets wrong, and why.** By CV the simulated ΔT coefficient "
        f"spreads {t1['sim0_cv']:.3f} (white noise), {t1['sim1_cv']:.3f} (simulator "
        f"defaults) and {t1['sim2_cv']:.3f} (strong slow bias noise) against Table 1's "
        f"{t1['comb_cv']:.2f}: {min(cv_gap):.0f}–{max(cv_gap):.0f}× less. Part of that gap "
        "is the mean, not the spread: Table 1's mean ΔT coefficient is "
        f"{abs(t1['comb_mean']) / t1['comb_sem']:.2f} standard errors from zero, while the "
        f"simulator's true one is {true_dt:.3f} °/s/°C at "
        f"{T_MID_C:g} °C (axis x default). In units of the temperature slope the "
        f"defaults spread {t1['comb_per_slope'] / t1['sim1_per_slope']:.0f}× less than "
        f"Table 1 ({t1['sim1_per_slope']:.2f} vs {t1['comb_per_slope']:.2f}), white noise "
        f"alone {t1['comb_per_slope'] / t1['sim0_per_slope']:.0f}× less "
        f"({t1['sim0_per_slope']:.2f}), and only a strong, slow Gauss–Markov bias process "
        f"(150 °/h, τ 600 s) comes close ({t1['sim2_per_slope']:.2f}, "
        f"×{t1['sim2_per_slope'] / t1['comb_per_slope']:.2f} of Table 1's). This is "
        "consistent with the per-run fit turning correlated bias noise during the ramp into "
        "ΔT coefficients (ΔT = τ·dT/dt is large only during the ramp and a few time "
        f"constants, τ = {GyroParams().tau_s:g} s, after it, so a 5-min ramp gives a3 little "
        f"data): the default bias noise ({GyroParams().bias_instability_deg_per_h:g} °/h, "
        f"τ {GyroParams().bi_tau_s:g} s) is too weak, or too fast, for Tang's gyro. The means "
        "differ too: in temperature-slope units "
        f"abs(mean(a3 + a4·T)) is {t1['comb_mean_per_slope']:.2f} ± "
        f"{t1['sem_per_slope']:.2f} (standard error) for Table 1 and "
        f"{t1['sim1_mean_per_slope']:.1f} for the simulator's defaults, in line with §3: "
        "Tang's gyro responds far less to ΔT than the simulator's default. "
        f"corr(a3, a4) is {t1['sim0_corr_a3_a4']:.2f} for the white-noise simulation in °C "
        f"and {t1['corr_a3_a4']:.3f} in the paper's raw units (T* ≈ {t1['t_star']:.0f}); "
        f"correlated bias noise decorrelates them ({t1['sim2_corr_a3_a4']:.2f}). Per-run "
        "switch-on offsets only move a5 in per-run fits; in a pooled fit without per-run "
        "offsets they would leak into every coefficient (`diagnose` fits one offset per run).",
        "",
        "## 3. Table 2 and Fig. 6",
        "",
        *t2_lines,
        "",
        "The paper-model and 50/60-min errors are of the paper's order (simulated RMS "
        f"{t2['t2_paper (eq. 12)']:.4f} vs measured 0.0430 °/s), but the temperature-only "
        "model fitted on the 5-min run fails badly in the simulation "
        f"(RMS {t2['t2_t2 5 min']:.3f} °/s) while in the paper it is only 39 % worse than "
        "the T/ΔT model. The simulator's default ΔT coefficient (0.05 °/s per °C on x) "
        "makes a fast ramp's gradient dominate the bias; Tang's gyro responds far less "
        "to ΔT. Calibrating the simulator's ΔT terms to the paper's Table 2 ratios is the "
        "correction this comparison asks for. Fig. 6: the simulator's chamber bow "
        "(2.2 °C) gives the same ramp residual "
        f"for both ramps ({t2['fig6_30_res']:.2f} and {t2['fig6_60_res']:.2f} °C); "
        "measured, the faster ramp deviates more (0.84 vs 0.57 °C). A bow that grows "
        "with ramp rate (≈ rate^0.56 from the two points) would match both; the "
        "diagnosis cannot test it without chamber logs.",
        "",
        "## 4. The diagnosis on data with known answers",
        "",
        "Six runs (2 h, 10 Hz) from the independent generator (two-node thermal network, "
        "0.125 °C / 1.28 s readout, Gauss–Markov noise, switch-on offsets), with "
        "hysteresis and drift injected. `diagnose` was not told:",
        "",
        *demo_lines,
        "",
        f"Diagnosis time {demo['demo_s']:.1f} s including the simulator replay. Report and "
        "plots: `figures/findings/synthetic-report/report.md`.",
        "",
        "![residual vs T](figures/findings/synthetic-report/residual_vs_temperature.png)",
        "![before/after](figures/findings/synthetic-report/before_after.png)",
        "![measured vs simulated](figures/findings/synthetic-report/measured_vs_simulated.png)",
        "",
    ]
    OUT.write_text("\n".join(doc) + "\n", encoding="utf-8")
    print(f"wrote {OUT} and {FIG}")


if __name__ == "__main__":
    main()
