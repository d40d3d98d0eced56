"""Residual statistics that locate a model's misses (all on 1-s blocks, °/s).

For residuals e (each run's own mean removed: the switch-on offset):

* ``residual_rms_dps``: √mean(e²);
* ``residual_vs_temperature_dps``: RMS over 2 °C bins of the bin means of e —
  structure left in T;
* ``heating_minus_cooling_dps``: at equal T (2 °C bins holding both), mean e
  while the last move was heating minus while it was cooling, weighted by
  the smaller count — hysteresis and lag;
* ``rate_sign_difference_dps``: mean e while dT/dt > +0.002 °C/s minus while
  < −0.002 °C/s;
* ``large_gradient_excess_dps``: mean e in the top quarter of |ΔT| minus the
  bottom quarter — even functions of ΔT;
* ``first_10min_dps``: mean e in the first 600 s after power-on — warm-up;
* ``drift_dps_per_h``: least-squares slope of e against time since power-on;
* ``correlation_time_s``: integrated autocorrelation time of e;
* ``allan_deviation_<τ>s_dps``: overlapping Allan deviation of e at τ = 1, 10,
  100, 1000 s (IEEE Std 952-1997), pooled over runs; the white part of the
  raw output is ``arw_deg_per_rth`` (from first differences at the sample rate);
* ``offset_std_dps``: spread of the per-run offsets.

Comparing a measured statistic m with n simulator replays (:func:`replay_spread`,
:func:`z_score`, :func:`z_threshold`): z = (m − mean)/std over the replays, and
m is significant when |z| > t_{n−1}(1 − p/2)·√(1 + 1/n) with p = 0.0027 — the
measurement lies outside the 99.73 % prediction interval of one more replay.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from gyrotherm.analysis._prep import Prepared
from gyrotherm.analysis._score import integrated_time

FloatArray = NDArray[np.float64]
ALLAN_TAUS_S = (1, 10, 100, 1000)
RATE_THRESHOLD_C_PER_S = 0.002
#: two-sided tail probability of a statistic marked significant (the 3σ of a Gaussian)
SIGNIFICANCE_P = 0.0027
#: what each statistic needs to be defined, for the notes on statistics left out
STATISTIC_NEEDS = {
    "residual_vs_temperature_dps": "a 2 °C temperature bin holding at least 30 s",
    "heating_minus_cooling_dps": "a 2 °C temperature bin holding at least 30 s whose last "
    "move was heating and at least 30 s whose last move was cooling",
    "rate_sign_difference_dps": "at least 30 s with dT/dt > +0.002 °C/s and at least 30 s "
    "with dT/dt < −0.002 °C/s",
    "large_gradient_excess_dps": "a gradient |ΔT| that varies (its quartiles differ)",
    "first_10min_dps": "at least 60 s within 600 s of power-on",
    "correlation_time_s": "residuals that are not all equal",
    "offset_std_dps": "at least 2 runs",
}


def allan_deviation(series: Sequence[FloatArray], m: int) -> float:
    """Overlapping Allan deviation at m blocks, pooled over series (NaN if too short)."""
    num = 0.0
    count = 0
    for y in series:
        n = len(y)
        if n < 2 * m + 1:
            continue
        c = np.concatenate([[0.0], np.cumsum(y)])
        avg = (c[m:] - c[:-m]) / m
        d = avg[m:] - avg[:-m]
        num += float(np.sum(d * d))
        count += len(d)
    return math.sqrt(num / (2.0 * count)) if count else math.nan


def _binned(x: FloatArray, e: FloatArray, width: float) -> tuple[FloatArray, FloatArray]:
    k = np.floor(x / width).astype(np.int64)
    _, inv = np.unique(k, return_inverse=True)
    sums = np.bincount(inv, weights=e)
    counts = np.bincount(inv).astype(np.float64)
    return sums / counts, counts


def heating_minus_cooling(
    temperature_c: FloatArray, direction: FloatArray, e: FloatArray, width_c: float = 2.0
) -> float:
    k = np.floor(temperature_c / width_c).astype(np.int64)
    total = weight = 0.0
    for b in np.unique(k):
        inb = k == b
        up = inb & (direction > 0)
        down = inb & (direction < 0)
        nu, nd = int(up.sum()), int(down.sum())
        if nu >= 30 and nd >= 30:
            w = min(nu, nd)
            total += w * (float(e[up].mean()) - float(e[down].mean()))
            weight += w
    return total / weight if weight else math.nan


def residual_statistics(
    runs: Sequence[Prepared], residuals: Sequence[FloatArray], *, arw_deg_per_rth: float,
    offsets_dps: Sequence[float],
) -> dict[str, float]:
    """The statistics above; NaN where the runs cannot show one."""
    e = np.concatenate(residuals)
    t = np.concatenate([p.temperature_c for p in runs])
    d = np.concatenate([p.direction for p in runs])
    rate = np.concatenate([p.rate_c_per_s for p in runs])
    grad = np.abs(np.concatenate([p.delta_t_c for p in runs]))
    time = np.concatenate([p.time_s for p in runs])
    means, counts = _binned(t, e, 2.0)
    ok = counts >= 30
    up, down = rate > RATE_THRESHOLD_C_PER_S, rate < -RATE_THRESHOLD_C_PER_S
    q1, q3 = np.percentile(grad, [25, 75])
    early = time < 600.0
    tc = time - time.mean()
    stats: dict[str, float] = {
        "residual_rms_dps": float(np.sqrt(np.mean(e * e))),
        "residual_vs_temperature_dps": float(np.sqrt(np.average(means[ok] ** 2,
                                                                weights=counts[ok])))
        if ok.any() else math.nan,
        "heating_minus_cooling_dps": heating_minus_cooling(t, d, e),
        "rate_sign_difference_dps": float(e[up].mean() - e[down].mean())
        if up.sum() >= 30 and down.sum() >= 30 else math.nan,
        "large_gradient_excess_dps": float(e[grad >= q3].mean() - e[grad <= q1].mean())
        if q3 > q1 else math.nan,
        "first_10min_dps": float(e[early].mean()) if early.sum() >= 60 else math.nan,
        "drift_dps_per_h": float(np.sum(tc * e) / np.sum(tc * tc) * 3600.0),
        "correlation_time_s": integrated_time(list(residuals)),
    }
    for tau in ALLAN_TAUS_S:
        stats[f"allan_deviation_{tau}s_dps"] = allan_deviation(residuals, tau)
    stats["arw_deg_per_rth"] = arw_deg_per_rth
    stats["offset_std_dps"] = float(np.std(offsets_dps, ddof=1)) if len(offsets_dps) > 1 \
        else math.nan
    return stats


def gauss_markov_fit(residuals: Sequence[FloatArray], *, max_lag: int = 600) -> tuple[
    float, float
]:
    """σ (°/s) and correlation time (s) of a first-order Gauss–Markov process fitted
    to the autocovariance of the 1-s residuals at lags ≥ 1 (white noise only
    affects lag 0). Returns (0, 100) when no positive correlation is seen."""
    lags = min(max_lag, min(len(r) for r in residuals) // 3)
    if lags < 3:
        return 0.0, 100.0
    acov = np.zeros(lags)
    for r in residuals:
        r = r - r.mean()
        n = len(r)
        f = np.fft.rfft(r, 2 * n)
        acov += np.fft.irfft(f * np.conj(f))[:lags] / n
    acov /= len(residuals)
    k = np.arange(1, lags)
    c = acov[1:]
    keep = c > 0.1 * max(float(c[0]), 1e-30)
    stop = int(np.argmin(keep)) if not keep.all() else len(c)
    if stop < 3:
        return 0.0, 100.0
    slope, intercept = np.polyfit(k[:stop], np.log(c[:stop]), 1)
    if slope >= 0:
        return 0.0, 100.0
    tau = float(min(max(-1.0 / slope, 2.0), 5000.0))
    return float(math.sqrt(math.exp(intercept))), tau


def statistic_requirement(name: str) -> str:
    """What the runs must hold for statistic ``name`` to be defined (else it is NaN)."""
    if name.startswith("allan_deviation_"):
        tau = int(name.removeprefix("allan_deviation_").removesuffix("s_dps"))
        return f"a run of at least {2 * tau + 1} s"
    return STATISTIC_NEEDS.get(name, "enough data")


def replay_spread(values: Sequence[float]) -> tuple[float, float, int]:
    """Mean, sample standard deviation (ddof 1) and count of the finite ``values``
    (NaN mean/std when fewer than 2 are finite)."""
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=np.float64)
    if len(v) < 2:
        return (float(v[0]) if len(v) else math.nan), math.nan, len(v)
    return float(v.mean()), float(v.std(ddof=1)), len(v)


def z_score(measured: float, mean: float, std: float) -> float:
    """(measured − mean) / std, with std floored at 10⁻⁹ of the values' scale (and
    10⁻³⁰) so that replays that all agree give a large finite |z| for a different
    measurement and 0 for an equal one; NaN when any input is NaN."""
    if not (math.isfinite(measured) and math.isfinite(mean) and math.isfinite(std)):
        return math.nan
    floor = max(1e-9 * max(abs(measured), abs(mean)), 1e-30)
    return (measured - mean) / max(std, floor)


def z_threshold(n_replays: int, p: float = SIGNIFICANCE_P) -> float:
    """|z| beyond which a measured statistic is significant, given ``n_replays`` replays.

    If the measurement were one more draw from the replays' distribution (normal,
    mean and std unknown), (m − mean)/(std·√(1 + 1/n)) would follow Student's t with
    n − 1 degrees of freedom; the threshold is the two-sided ``p`` quantile of that
    (the 3σ of a Gaussian for the default p = 0.0027): t_{n−1}(1 − p/2)·√(1 + 1/n).
    7.25 for n = 5, 4.80 for n = 8, → 3 as n → ∞. NaN for n < 2.
    """
    if n_replays < 2:
        return math.nan
    from scipy.stats import t as student_t

    return float(student_t.ppf(1.0 - p / 2.0, n_replays - 1)) * math.sqrt(1.0 + 1.0 / n_replays)
