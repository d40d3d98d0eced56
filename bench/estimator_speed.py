"""Offline estimator and fit speed: µs per row of `estimate_series` vs a bare filterpy loop.

Baseline: the same filterpy KalmanFilter predict/update loop with fixed F and Q and no
gating, measured in the same run. Also times a pooled `paper` fit of seven runs.

    python bench/estimator_speed.py            # prints JSON on stdout
"""

from __future__ import annotations

import json
import statistics
import sys
import time

import numpy as np
from filterpy.kalman import KalmanFilter

from gyrotherm.compensation import features, fit
from gyrotherm.estimators import EstimatorConfig, estimate_series
from gyrotherm.sim import PAPER_HEATING_MIN, chamber_runs

REPEATS = 7


def _bare_filterpy(time_s: np.ndarray, temp_c: np.ndarray) -> None:
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.H = np.array([[1.0, 0.0]])
    kf.R = np.array([[4e-4]])
    dt = float(time_s[1] - time_s[0])
    f = np.array([[1.0, dt], [0.0, 1.0]])
    q = 1e-7 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    kf.x = np.array([[temp_c[0]], [0.0]])
    z = np.zeros((1, 1))
    for v in temp_c.tolist():
        kf.predict(F=f, Q=q)
        z[0, 0] = v
        kf.update(z)


def _us_per_row(fn, n: int) -> float:  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) / n * 1e6


def main() -> int:
    run = chamber_runs([30], seed=1, rate_hz=10.0)[0]
    n = len(run)
    cfg = EstimatorConfig()
    # interleaved repeats: a change of machine speed hits both sides alike
    ours_us, bare_us = [], []
    for _ in range(REPEATS):
        ours_us.append(_us_per_row(lambda: estimate_series(run.time_s, run.temperature_c, cfg), n))
        bare_us.append(_us_per_row(lambda: _bare_filterpy(run.time_s, run.temperature_c), n))
    ours, bare = statistics.median(ours_us), statistics.median(bare_us)
    paired = statistics.median(o / b for o, b in zip(ours_us, bare_us, strict=True))
    runs = chamber_runs(PAPER_HEATING_MIN, seed=1, rate_hz=10.0)
    t0 = time.perf_counter()
    feats = [features(r, cfg) for r in runs]
    t1 = time.perf_counter()
    fit(feats, "paper", estimator=cfg)
    t2 = time.perf_counter()
    out = {
        "rows": n,
        "estimate_series_us_per_row_median": round(ours, 2),
        "bare_filterpy_us_per_row_median": round(bare, 2),
        "ratio_vs_bare": round(ours / bare, 3),
        "paired_ratio_median": round(paired, 3),
        "seven_runs_rows": sum(len(r) for r in runs),
        "seven_runs_features_s": round(t1 - t0, 2),
        "seven_runs_pooled_fit_s": round(t2 - t1, 3),
    }
    print(json.dumps(out))
    print(f"estimator {ours:.1f} µs/row vs bare filterpy {bare:.1f} µs/row "
          f"(×{ours / bare:.2f}); 7 runs: features {t1 - t0:.1f} s, fit {t2 - t1:.2f} s",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
