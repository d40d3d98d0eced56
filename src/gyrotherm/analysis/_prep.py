"""Preparing runs for the diagnosis: sensor settings, T/ΔT features, 1-s blocks.

Per run (one rate axis):

1. the temperature readout is characterised from the readings themselves:
   refresh period (the lattice every change sits on, :func:`_refresh_from_changes`),
   LSB (the grid the readings sit on) and white noise (one reading per refresh about
   a local quartic, less the quantisation, :func:`_white_noise`);
   tests/analysis/test_readout_table.py checks all three against the synthetic
   generator's truth over refresh 0.05…1.3 s, LSB 0.0625…1 °C and 10…200 Hz;
2. the product's Kalman estimator (:func:`gyrotherm.estimators.estimate_series`)
   runs over the readings, fed at most once per ``max(update period, 1 s)``,
   giving T and dT/dt; ΔT = τ·dT/dt, where τ is regressed from the logged
   chamber temperature when runs carry ``chamber_c``
   (chamber − T = τ·dT/dt − P, P = self-heating) and defaults to 120 s otherwise
   (the bias models are linear in ΔT, so τ only rescales ΔT coefficients);
3. everything is averaged over 1-s blocks of time since power-on. White noise
   above 0.5 Hz carries no bias information; the blocks make a 1 kHz run and a
   10 Hz run cost the same and give the residual statistics a common footing;
4. the direction of the last temperature move (``direction``: +1 heating,
   −1 cooling, 0 before the first move) is a play operator on T of width
   ``direction_width_c`` (0.25 °C): it flips only after T has moved that far
   from its last extreme, and it keeps its sign through holds (the hysteresis
   regressor then saturates towards it with the temperature travelled, so a
   small wiggle moves it little).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import savgol_coeffs, savgol_filter

from gyrotherm._errors import CalibrationError
from gyrotherm.analysis._effects import DIRECTION_WIDTH_C, direction_state
from gyrotherm.codecs import Run
from gyrotherm.compensation._fit_offsets import BLOCK_S, block_mean, blocks
from gyrotherm.estimators import EstimatorConfig, estimate_series

FloatArray = NDArray[np.float64]
DEFAULT_TAU_S = 120.0


@dataclass(frozen=True)
class Readout:
    """What the runs say about the temperature readout and the rate output."""

    period_s: float
    lsb_c: float
    noise_c: float
    sample_rate_hz: float
    rate_lsb_dps: float
    sample_noise_dps: float
    """Per-sample standard deviation of the rate's white part, °/s (first differences / √2)."""
    refresh_period_s: float = 0.0
    """The readout's refresh period, not rounded to the row interval (mean of the single
    refresh intervals, e.g. 1.28 s where ``period_s`` says 1.3 s at 10 Hz), s; 0: unknown."""
    white_noise_c: float = 0.0
    """The readings' white noise σ before rounding, °C (:func:`_white_noise`; 0 where the
    rounding hides it). ``noise_c`` is the scatter between successive *changes* of the
    reading, √(σ² + LSB²/12) or one LSB step (LSB/√2) where the rounding hides σ: the
    quantity the estimator settings, the lag's null replay and the simulator calibration
    were validated with."""


@dataclass(frozen=True)
class Prepared:
    """One run on 1-s blocks: time since power-on, features and the rate of one axis."""

    name: str
    time_s: FloatArray
    temperature_c: FloatArray
    rate_c_per_s: FloatArray
    delta_t_c: FloatArray
    chamber_c: FloatArray | None
    rate_dps: FloatArray
    counts: FloatArray
    direction: FloatArray

    def __len__(self) -> int:
        return len(self.time_s)


def _grid_step(values: FloatArray, *, floor: float) -> float:
    """The grid spacing the values sit on (0 when they do not look quantised)."""
    u = np.unique(np.round(values, 9))
    if len(u) < 3:
        return 0.0
    d = np.diff(u)
    step = float(np.min(d[d > floor])) if np.any(d > floor) else 0.0
    if step <= 0:
        return 0.0
    k = (u - u[0]) / step
    return step if float(np.max(np.abs(k - np.round(k)))) < 0.05 else 0.0


#: A gap "fits" a candidate P' when it is a whole multiple of P' within this many row
#: intervals (a change is seen at the first row after its refresh: up to one row off
#: per gap, whole rows when the refresh is commensurate with the rows; 10 % for the
#: stamps' jitter).
_FIT_ROWS = 1.1
#: The least share of gaps that must fit a candidate of the comb.
_FIT_MIN = 0.8
#: The least share of changes that must sit on the candidate's lattice.
_LATTICE_MIN = 0.9
#: The shortest refresh told from the rows, in row intervals: a lattice of two rows
#: holds changes on rows of either parity when the refresh straddles the row stamps.
_MIN_REFRESH_ROWS = 2.2
_MAX_GAPS = 5000
#: Candidate × gap products scored at most (vectorised in chunks of ~2e6).
_COMB_BUDGET = 20_000_000
#: Largest-first comb candidates checked on the lattice before giving up.
_MAX_LATTICE_TRIES = 2000
#: The least share on the least-squares lattice (window widened by its uncertainty)
#: for the period to be scanned about it.
_LATTICE_QUICK = 0.8


def _comb(gaps: FloatArray, dt: float, lo: float, hi: float) -> tuple[FloatArray, FloatArray]:
    """Candidate refresh periods between ``lo`` and ``hi`` snapped to the comb each
    selects (the least-squares period of the gaps given their multiples
    n = round(g/P')), with the share of gaps within :data:`_FIT_ROWS` rows of a multiple.
    The candidates are log-spaced finely enough that n is right for the longer gaps
    (relative step dt / (4 · 90th percentile gap)), so a refresh that rarely changes
    the value (gaps of hundreds of refreshes) is still among them."""
    long_gap = float(np.quantile(gaps, 0.9))
    step = min(2e-3, dt / (4.0 * long_gap))
    count = int(min(max(math.log(hi / lo) / step, 2.0), 400_000))
    if count * len(gaps) > _COMB_BUDGET:  # evenly spread gaps: bounded cost
        keep = max(50, _COMB_BUDGET // count)
        gaps = _spread(gaps, keep)
    cand = np.geomspace(lo, hi, count)
    tol = _FIT_ROWS * dt
    snapped, fit = np.empty(count), np.empty(count)
    chunk = max(1, 2_000_000 // len(gaps))
    for s in range(0, count, chunk):
        p = cand[s:s + chunk, None]
        n = np.maximum(np.round(gaps[None, :] / p), 1.0)
        q = (n @ gaps) / np.einsum("ij,ij->i", n, n)
        snapped[s:s + chunk] = q
        fit[s:s + chunk] = np.mean(np.abs(gaps[None, :] - n * q[:, None]) <= tol, axis=1)
    return snapped, fit


def _most_within(resid: FloatArray, width: float) -> NDArray[np.int64]:
    """Per row of ``resid`` (sorted along each row), the most values in one window of
    ``width``."""
    m, n = resid.shape
    gap = float(np.ptp(resid)) + 2.0 * width + 1.0
    flat = (resid + gap * np.arange(m)[:, None]).ravel()
    inside = np.searchsorted(flat, flat + width, side="right") - np.arange(m * n)
    return np.asarray(np.max(inside.reshape(m, n), axis=1), dtype=np.int64)


def _lattice(tc: FloatArray, q: float, dt: float) -> tuple[float, float, float, float]:
    """The refresh P near ``q`` on which the change times ``tc`` sit, the share of
    changes that sit on it, how far about the least-squares P the scan reached, and a
    refresh instant φ (the start of the window that holds the most changes).

    Each change is seen on the first row after a refresh φ + k·P, so t_c − (φ + k_c·P)
    lies within one row interval for every change. The refresh indices k_c are
    unwrapped along the run from the gaps (k_{c+1} − k_c = round(gap/q)), then φ and P
    are fitted by least squares over the whole run and k_c reassigned (three rounds):
    a long baseline, so a comb that only fits the gaps locally (0.73 s against a
    0.64-s refresh whose value changes every 7–8 refreshes, 3 rows against a 1-row
    refresh) drifts off the changes. The share is the most changes t_c − k_c·P in one
    window of 1.1 row intervals, the largest over P scanned ±4 least-squares errors
    about the fit (a few changes leave the least squares a row or two off over a long
    run); the scan runs only where the share at the fit, the window widened by that
    uncertainty, reaches :data:`_LATTICE_QUICK`."""
    n = len(tc)
    k = np.r_[0.0, np.cumsum(np.maximum(np.round(np.diff(tc) / q), 1.0))]
    period, phase = q, float(tc[0])
    for _ in range(3):
        kc = k - k.mean()
        period = float(np.dot(kc, tc - tc.mean()) / np.dot(kc, kc))
        if not period > 0:
            return q, 0.0, 0.0, 0.0
        phase = float(tc.mean() - period * k.mean())
        k = np.round((tc - phase) / period)
    span = max(float(np.ptp(k)), 1.0)
    reach = 4.0 * dt / (max(float(np.std(k)), 1.0) * math.sqrt(n))
    width = _FIT_ROWS * dt
    resid = np.sort(tc - k * period)[None, :]
    if _most_within(resid, width + reach * span / 2.0)[0] < _LATTICE_QUICK * n:
        return period, 0.0, reach, 0.0
    # steps drifting 2 % of a row over the run
    steps = min(400, 1 + 2 * int(reach * span / (0.02 * dt)))
    periods = period + np.linspace(-reach, reach, steps)
    best, most = period, -1
    chunk = max(1, 2_000_000 // n)
    for s in range(0, steps, chunk):
        p = periods[s:s + chunk]
        inside = _most_within(np.sort(tc[None, :] - k[None, :] * p[:, None], axis=1), width)
        i = int(np.argmax(inside))
        if inside[i] > most:
            best, most = float(p[i]), int(inside[i])
    resid = np.sort(tc - k * best)
    start = np.searchsorted(resid, resid + width, side="right") - np.arange(n)
    return best, most / n, reach, float(resid[int(np.argmax(start))])


def _refresh_from_changes(t: FloatArray, change: NDArray[np.int64],
                          dt: float) -> tuple[float, float | None]:
    """The readout's refresh period from the times its value changed (s), and one of
    its refresh instants (None where every row is taken as fresh).

    A reading can only change at a refresh, so every gap g between two changes is a
    whole multiple n·P of the refresh P, give or take the row grid (a change is seen
    at the first row after its refresh). A quantised, slowly moving temperature
    repeats its value for several refreshes, so the gaps' small percentiles or their
    minimum give 2P, 5P …, not P. Two steps:

    1. the comb (:func:`_comb`): candidates that fit ≥ :data:`_FIT_MIN` of the gaps
       within a row. The refresh and its divisors fit every gap; so, locally, do
       combs that only match the gaps' strides within a row (3 rows against a 1-row
       refresh, 0.73 s against 0.64 s when the value changes every 7–8 refreshes);
    2. the lattice (:func:`_lattice`): from the largest candidate down, the first
       whose whole-run lattice holds ≥ :data:`_LATTICE_MIN` of the changes within a
       row, and is at least :data:`_MIN_REFRESH_ROWS` rows long, is the refresh
       (fitted over the whole run).

    Candidates stop at the shortest gap plus a row (no refresh is longer). Changes on
    consecutive rows (shortest gap one row), or no candidate on its lattice, mean
    every row is fresh (refresh = dt): a refresh under about two rows cannot be told
    from the rows."""
    tc = t[change]
    gaps = np.diff(tc)
    lo, hi = 1.5 * dt, float(np.min(gaps)) + _FIT_ROWS * dt  # a row late, jittered stamps
    if hi <= lo or np.count_nonzero(gaps < lo) > 0.01 * len(gaps):
        return dt, None  # changes on consecutive rows: every row is fresh
    gaps = _spread(gaps, _MAX_GAPS)  # the whole run, bounded cost
    snapped, fit = _comb(gaps, dt, lo, hi)
    # the refresh fits (almost) every gap; with a row's tolerance a short comb fits
    # most of them by chance, so only the combs that fit nearly as well are tried
    least = max(_FIT_MIN, float(np.max(fit)) - 0.1)
    ok = np.sort(snapped[(fit >= least) & (snapped >= _MIN_REFRESH_ROWS * dt)])[::-1]
    tried = 0
    covered = math.inf  # the least period the lattices tried so far reached
    for q in ok.tolist():
        if q >= covered:
            continue
        period, share, reach, phase = _lattice(tc, q, dt)
        if share >= _LATTICE_MIN and period >= _MIN_REFRESH_ROWS * dt:
            return _longest_multiple(tc, period, phase, hi, dt)
        covered = min(q, period) - max(reach, 1e-9 * q)
        tried += 1
        if tried >= _MAX_LATTICE_TRIES:
            break
    if len(ok):  # the combs that fit the gaps first (a narrower range: a longer scan)
        narrow = max(lo, float(ok[-1]) * (1 - 1e-3)), min(hi, float(ok[0]) * (1 + 1e-3))
        scanned = _phase_scan(tc, *narrow, dt)
        if scanned[1] is not None:
            return scanned
    return _phase_scan(tc, lo, hi, dt)


#: The phase scan (:func:`_phase_scan`): the changes its coarse stage takes (at least,
#: at most), its most periods, how many of its candidates it refines over the whole run, and
#: the most changes the refinement judges (a bounded cost: well under a second).
_SCAN_MIN_CHANGES = 12
_SCAN_COARSE_CHANGES = 40
_SCAN_PERIODS = 30_000
_SCAN_REFINE = 8
_SCAN_CHANGES = 1000
#: How far (relative) a multiple k·P of a lattice's period is searched about k·P.
_MULTIPLE_REL = 2e-3


def _spread(values: FloatArray, most: int) -> FloatArray:
    """``values``, or ``most`` of them evenly spread (the first and last kept)."""
    if len(values) <= most:
        return values
    return values[np.linspace(0, len(values) - 1, most).astype(np.int64)]


def _aligned(t0: FloatArray, periods: FloatArray, width: float) -> NDArray[np.int64]:
    """Per period P, the most of the change times ``t0`` whose phase t mod P falls in
    one window of ``width`` (wrapping round)."""
    n = len(t0)
    out = np.empty(len(periods), dtype=np.int64)
    chunk = max(1, 1_000_000 // n)
    for s in range(0, len(periods), chunk):
        p = periods[s:s + chunk, None]
        off = np.sort(np.mod(t0[None, :], p), axis=1)
        out[s:s + chunk] = np.minimum(_most_within(np.hstack([off, off + p]), width), n)
    return out


def _refine_period(t0: FloatArray, q: float, step: float, known_s: float,
                   dt: float) -> float:
    """The period about ``q`` (±``step``, right over the first ``known_s`` seconds of the
    change times ``t0``) on which the most changes line up, over spans 4× longer each
    time up to the whole of ``t0``: at each span, steps that move its last change by
    dt/8, over the previous span's best plateau (every period that held the most
    changes) and 2 of its steps either side; the next span starts from the plateau's
    middle (tens of periods a span, whatever the run's length)."""
    width = _FIT_ROWS * dt
    span = float(t0[-1])
    p, s = q, max(known_s, dt)
    while True:
        s = min(span, 4.0 * s)
        sub = t0[t0 <= s]
        fine = dt * p / (8.0 * s)
        k = np.arange(-math.ceil(step / fine), math.ceil(step / fine) + 1, dtype=np.float64)
        periods = np.asarray(p + k * fine, dtype=np.float64)
        score = _aligned(sub, periods, width)
        best = periods[score == score.max()]  # a plateau: every period holding them
        p = float(best.mean())
        step = float(best.max() - best.min()) / 2.0 + 2.0 * fine
        if s >= span:
            return p


def _phase_scan(tc: FloatArray, lo: float, hi: float, dt: float
                ) -> tuple[float, float | None]:
    """When no lattice unwrapped from the gaps holds the changes: the refresh on which
    the change times line up, scanned directly. Unwrapping the refresh count of each gap
    fails when the value stays put for hundreds of refreshes (a 1 °C reading on a hold):
    a candidate 0.1 % off miscounts a 300-s gap by three refreshes.

    Coarse: every period in [``lo``, ``hi``] (the range of the comb candidates that fit
    the gaps, then the whole candidate range), in steps that move the first
    :data:`_SCAN_COARSE_CHANGES` changes' last one by dt/4 (the window is 1.1 rows),
    scored by how many of those
    changes fall in one window of :data:`_FIT_ROWS` rows of their phase t mod P. Fine:
    over each contiguous band of coarse periods holding ≥ :data:`_LATTICE_MIN` of those
    changes (at most :data:`_SCAN_REFINE` bands, longest first), from the band's middle
    over spans 4× longer each time (:func:`_refine_period`), scored on (up to
    :data:`_SCAN_CHANGES` of) all the changes. Of the refined periods holding
    ≥ :data:`_LATTICE_MIN` of them and at least :data:`_MIN_REFRESH_ROWS` rows long, the
    one holding the most is the refresh, the longest among near-ties (within 1 % of the
    changes: the refresh's divisors hold them all too); else every row is taken as
    fresh."""
    width = _FIT_ROWS * dt
    t0 = tc - tc[0]
    m = min(len(t0), _SCAN_COARSE_CHANGES)
    if not hi > lo:
        return dt, None
    per_s = 4.0 * math.log(hi / lo) / dt  # coarse periods per second of span
    while m > _SCAN_MIN_CHANGES and per_s * float(t0[m - 1]) > _SCAN_PERIODS:
        m -= 1
    if m < _SCAN_MIN_CHANGES or not t0[m - 1] > 0:
        return dt, None
    head = t0[:m]
    count = int(min(per_s * float(head[-1]), _SCAN_PERIODS)) + 2
    coarse = np.geomspace(lo, hi, count)
    score = _aligned(head, coarse, width)
    passing = np.flatnonzero(score >= _LATTICE_MIN * m)
    everyone = _spread(t0, _SCAN_CHANGES)
    rel = math.log(hi / lo) / max(count - 1, 1)  # one coarse step, relative
    # contiguous bands of passing coarse periods, longest first (P/2, P/3 pass too)
    bands = np.split(passing, np.flatnonzero(np.diff(passing) > 1) + 1) if len(passing) else []
    scored: list[tuple[int, float]] = []
    for band in sorted(bands, key=lambda b: -int(b[-1]))[:_SCAN_REFINE]:
        a, b = float(coarse[band[0]]), float(coarse[band[-1]])
        period = _refine_period(everyone, math.sqrt(a * b), (b - a) / 2.0 + rel * b,
                                float(head[-1]), dt)
        inside = int(_aligned(everyone, np.array([period]), width)[0])
        if inside >= _LATTICE_MIN * len(everyone) and period >= _MIN_REFRESH_ROWS * dt:
            scored.append((inside, period))
    if not scored:
        return dt, None
    most = max(n for n, _ in scored)  # the best; among near-ties the longest
    period = max(p for n, p in scored if n >= most - 0.01 * len(everyone))
    return period, _phase_of(tc, period, dt)


def _phase_of(tc: FloatArray, period: float, dt: float) -> float:
    """A refresh instant of ``period``: the start of the one-window (1.1 rows) span of
    phases t mod P that holds the most of the change times ``tc``."""
    off = np.sort(np.mod(tc - tc[0], period))
    both = np.r_[off, off + period]
    start = np.searchsorted(both, both + _FIT_ROWS * dt, side="right") - np.arange(len(both))
    return float(tc[0] + both[int(np.argmax(start))] % period)


def _longest_multiple(tc: FloatArray, period: float, phase: float, hi: float,
                      dt: float) -> tuple[float, float]:
    """``period`` or its longest multiple k·P ≤ ``hi`` on which ≥ :data:`_LATTICE_MIN` of
    the changes (up to :data:`_SCAN_CHANGES` of them) still line up, and its phase: a
    lattice unwrapped from the gaps can settle on P/2 when its candidate near P failed
    (every change sits on the P/2 lattice too)."""
    sub = _spread(tc, _SCAN_CHANGES)
    t0 = sub - sub[0]
    head = float(t0[min(len(t0), _SCAN_COARSE_CHANGES) - 1])
    best = period
    for k in range(2, int(hi / period * (1 + _MULTIPLE_REL)) + 1):
        # k·P carries k times P's error: refined about it before it is judged
        kp = _refine_period(t0, k * period, _MULTIPLE_REL * k * period, head, dt)
        held = int(_aligned(t0, np.array([kp]), _FIT_ROWS * dt)[0])
        if held >= _LATTICE_MIN * len(t0):
            best = kp
    return (period, phase) if best == period else (best, _phase_of(tc, best, dt))


#: The window of the local polynomial the white noise is measured about, s, and its
#: least number of readings (the filter's own share of a reading, h₀, stays ≤ 4 %).
_NOISE_WINDOW_S = 40.0
_NOISE_MIN_POINTS = 101
#: White noise below this many LSB is reported as 0 (hidden by the rounding).
_NOISE_HIDDEN_LSB = 0.25


def _white_noise(t: FloatArray, temp: FloatArray, refresh_s: float, phase_s: float | None,
                 lsb_c: float) -> float:
    """White noise of the readings, °C.

    One reading per refresh, taken at the last row before the middle of its slot
    (refresh instants ``phase_s`` + k·``refresh_s``; every row where ``phase_s`` is
    None), so that the readings are evenly spaced in the time they were *sampled*
    (a row's time is up to a refresh later: on a 10 °C/min warm-up that is several
    LSB of spurious scatter). Their scatter about a local quartic (Savitzky–Golay
    over ≥ :data:`_NOISE_MIN_POINTS` readings and ≥ :data:`_NOISE_WINDOW_S`), divided
    by 1 − h₀ (the filter's own share), less the quantisation's LSB²/12. A noiseless
    rounded temperature scatters at most about LSB²/12 about a smooth curve (a
    sawtooth whatever its rate), so it reads ≈ 0; a short difference filter reads its
    regular steps (one LSB every other refresh) as noise. Valid while σ ≳ LSB/2;
    an estimate below :data:`_NOISE_HIDDEN_LSB` LSB is reported as 0 (the sawtooth's
    own scatter differs from LSB²/12 by up to ~15 % over a run)."""
    if phase_s is None:
        y, spacing = temp, float(np.median(np.diff(t)))
    else:
        first = math.ceil((t[0] - phase_s) / refresh_s)
        mids = phase_s + (np.arange(first, math.floor((t[-1] - phase_s) / refresh_s)) + 0.5) \
            * refresh_s
        rows = np.searchsorted(t, mids, side="right") - 1
        y, spacing = temp[rows[rows >= 0]], refresh_s
    width = max(_NOISE_MIN_POINTS, int(_NOISE_WINDOW_S / spacing))
    width += 1 - width % 2
    if len(y) < 2 * width:
        if len(y) < 7:
            return 0.02
        total = float(np.var(np.diff(y, 2))) / 6.0  # a linear trend drops out
    else:
        h0 = float(savgol_coeffs(width, 4)[width // 2])
        resid = y - savgol_filter(y, width, 4, mode="interp")
        half = width // 2
        total = float(np.mean(resid[half:-half] ** 2)) / (1.0 - h0)
    white = math.sqrt(max(total - lsb_c * lsb_c / 12.0, 0.0))
    # a noiseless rounded ramp's sawtooth scatters LSB²/12 give or take ~15 % over a run
    # (σ up to ~LSB/8 from nothing): below LSB/4 the rounding hides the noise
    return white if white >= _NOISE_HIDDEN_LSB * lsb_c else 0.0


def characterise(run: Run, axis: str) -> Readout:
    """Readout period, LSB and noise of the temperature sensor; rate LSB and noise.

    ``refresh_period_s``: :func:`_refresh_from_changes`; ``period_s``: that period on
    the row grid (a multiple of the row interval); ``lsb_c``: the grid the readings sit
    on; ``white_noise_c``: :func:`_white_noise`; ``noise_c``: the scatter between
    changes (the field's docstring)."""
    t = run.time_s
    if len(t) < 10:
        raise CalibrationError(f"{run.source}: run {run.name!r} has {len(t)} rows, need ≥ 10")
    dt = float(np.median(np.diff(t)))
    temp = run.temperature_c
    change = np.flatnonzero(np.diff(temp) != 0) + 1
    refresh, phase = _refresh_from_changes(t, change, dt) if len(change) > 10 else (dt, None)
    period = dt * round(refresh / dt) if refresh > 1.5 * dt else dt
    lsb = _grid_step(temp[: min(len(temp), 200_000)], floor=1e-7)
    white = _white_noise(t, temp, refresh, phase, lsb)
    noise = max(math.sqrt(white * white + lsb * lsb / 12.0), lsb / math.sqrt(2)) if lsb > 0 \
        else white
    rate = run.rates_dps[axis]
    rate_lsb = _grid_step(rate[: min(len(rate), 200_000)], floor=1e-9)
    return Readout(
        period_s=period,
        lsb_c=lsb,
        noise_c=min(max(noise, 1e-3), 5.0),
        sample_rate_hz=1.0 / dt,
        rate_lsb_dps=rate_lsb,
        sample_noise_dps=float(np.std(np.diff(rate)) / math.sqrt(2)),
        refresh_period_s=refresh,
        white_noise_c=white,
    )


def estimator_for(readouts: Sequence[Readout], tau_s: float = DEFAULT_TAU_S) -> EstimatorConfig:
    """Estimator settings matching the readout, chosen by held-out deployed error
    (``scripts/estimator_study.py``, docs/findings.md §6 "Estimator settings"): every new
    reading is fed (``update_period_s`` = the refresh period :func:`characterise`
    measures; before: one per max(refresh, 1 s), which threw most readings of a fast
    sensor away); noise = the scatter :func:`characterise` measures less LSB/√6 (a
    quantised, noiseless-looking reading: its noise is the quantisation itself; the
    white-noise estimate alone was worse with a coarse LSB and a fast refresh); q stays
    1e-7 °C²/s³ (1e-8 and 1e-6 were worse); τ is a scale of ΔT the calibration's
    coefficients absorb (no effect on the deployed error)."""
    period = float(np.median([r.refresh_period_s or r.period_s for r in readouts]))
    lsb = float(np.median([r.lsb_c for r in readouts]))
    noise = float(np.median([r.noise_c for r in readouts]))
    noise = max(noise - lsb / math.sqrt(6), 0.005) if lsb > 0 else noise
    return EstimatorConfig(tau_s=tau_s, noise_c=noise, quantisation_c=max(lsb, 1e-4),
                           update_period_s=period)


def prepare(
    run: Run,
    axis: str,
    estimator: EstimatorConfig,
    *,
    direction_width_c: float = DIRECTION_WIDTH_C,
    features: str = "smooth",
) -> Prepared:
    """Features of ``run`` on 1-s blocks (ΔT with ``estimator.tau_s``).

    ``features="smooth"`` (default): T and dT/dt from a zero-phase
    Savitzky–Golay fit (order 2; 31 s for T, 61 s for dT/dt) to the 1-s block
    means of the readings, so that no estimator lag is mistaken for physics.
    ``features="kalman"``: the product's causal estimator, as the daemon sees it.
    """
    if axis not in run.rates_dps:
        raise CalibrationError(
            f"{run.source}: run {run.name!r} has no rate axis {axis!r} (has {list(run.axes)})"
        )
    inverse, counts = blocks(run.time_s)
    if features == "kalman":
        est = estimate_series(run.time_s, run.temperature_c, estimator)
        temp = block_mean(est.temperature_c, inverse, counts)
        rate_c = block_mean(est.rate_c_per_s, inverse, counts)
    elif features == "smooth":
        raw = block_mean(run.temperature_c, inverse, counts)
        temp, rate_c = _smooth(raw)
    else:
        raise CalibrationError(f"features = {features!r}: expected 'smooth' or 'kalman'")
    chamber = None if run.chamber_c is None else block_mean(run.chamber_c, inverse, counts)
    return Prepared(
        name=run.name,
        time_s=block_mean(run.time_s, inverse, counts),
        temperature_c=temp,
        rate_c_per_s=rate_c,
        delta_t_c=estimator.tau_s * rate_c,
        chamber_c=chamber,
        rate_dps=block_mean(run.rates_dps[axis], inverse, counts),
        counts=counts,
        direction=direction_state(temp, direction_width_c),
    )


def _smooth(raw: FloatArray) -> tuple[FloatArray, FloatArray]:
    n = len(raw)
    if n < 7:
        return raw.copy(), np.zeros(n)
    w_t = min(31, n - 1 if n % 2 == 0 else n)
    w_d = min(61, n - 1 if n % 2 == 0 else n)
    temp = savgol_filter(raw, w_t, 2, mode="interp")
    rate = savgol_filter(raw, w_d, 2, deriv=1, delta=BLOCK_S, mode="interp")
    return np.asarray(temp, dtype=np.float64), np.asarray(rate, dtype=np.float64)


def with_tau(p: Prepared, tau_s: float) -> Prepared:
    """The same run with ΔT rescaled to the time constant ``tau_s``."""
    from dataclasses import replace

    return replace(p, delta_t_c=tau_s * p.rate_c_per_s)


def fit_tau(runs: Sequence[Prepared]) -> tuple[float, float] | None:
    """τ and self-heating P from chamber − T = τ·dT/dt − P (least squares, all runs).

    None when no run logs the chamber or the temperature never changes.
    """
    rows = [(p.chamber_c - p.temperature_c, p.rate_c_per_s) for p in runs
            if p.chamber_c is not None]
    if not rows:
        return None
    y = np.concatenate([r[0] for r in rows])
    x = np.concatenate([r[1] for r in rows])
    if float(np.std(x)) < 1e-5:
        return None
    a = np.column_stack([x, np.ones_like(x)])
    (tau, c), *_ = np.linalg.lstsq(a, y, rcond=None)
    if not (1.0 <= tau <= 1e5):
        return None
    return float(tau), float(-c)
