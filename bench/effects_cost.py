"""Daemon cost of an extended (version-2) calibration against the paper calibration.

The daemon's per-frame core, :class:`gyrotherm.daemon.Pipeline` (decode →
estimate → compensate → encode → hand to a sink that discards), is fed the same
pre-built CAN frames of a 1 kHz gyro with 10 Hz temperature frames (1 % of the
frames) under three calibrations:

* ``paper``: version 1, Tang et al.'s eq. 11 on every axis (the baseline);
* ``richest``: version 2, every axis with all six effects (thermal lag,
  hysteresis, warm-up, cubic, gradient², drift): the most a calibration can ask;
* ``none``: no calibration (the floor: decode, estimate, encode, publish);
* ``richest_zero_pending``: ``richest`` with a boot-time zero that never accepts a
  window (``max_std_dps`` 1e-6, no deadline within the trial): every rate frame
  feeds the zero, its worst case (it lasts at most ``deadline_s`` on a vehicle);
* ``richest_zero_done``: ``richest`` with a zero accepted after 1 s: the state
  the daemon is in for the rest of a power-on.

Trials are interleaved round-robin (paper, richest, none, paper, …) so load changes
hit all alike; each trial times ``Pipeline.process`` over all frames with
``time.process_time`` (CPU of this process). Reported: median µs per frame, per
rate frame and per temperature frame (the compensation runs on temperature frames
only; the extended model adds its cost there), and the ratio richest / paper (the
issue's bound: ≤ 1.2 per frame), and each zero variant / paper. One JSON object on
stdout, a summary on stderr.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from typing import Any

import can
import numpy as np

from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
from gyrotherm.analysis._to_calibration import calibration_from_models
from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run
from gyrotherm.compensation import Calibration, Scaling, ValidRange, ZeroConfig
from gyrotherm.daemon import Pipeline
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import frames_from_run

SCALING = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=8.0)
ALL = {"thermal_lag": 75.0, "hysteresis": 0.35, "warmup": 400.0, "cubic": 0.0,
       "gradient_quadratic": 0.0, "drift": 0.0}
COLUMNS = (*BASE_COLUMNS, "hysteresis", "warmup", "cubic", "gradient_quadratic", "drift")


class _Discard:
    def put_rate(self, payload: bytes) -> None:
        return None

    def put_state(self, payload: bytes) -> None:
        return None


def calibrations() -> dict[str, Calibration | None]:
    def cal(effects: dict[str, float], columns: tuple[str, ...],
            coefficients: tuple[float, ...]) -> Calibration:
        model = ExtendedModel(SCALING, effects, columns, coefficients, intercept_dps=0.3)
        return calibration_from_models(
            {a: model for a in "xyz"}, estimator=EstimatorConfig(), t_on_max_s=7200.0,
            valid_range=ValidRange(-60.0, 90.0, -500.0, 500.0),
            provenance={"method": "bench"})

    paper = cal({}, BASE_COLUMNS, (0.02, -0.05, 0.03, 0.004))
    richest = cal(ALL, COLUMNS, (0.02, -0.05, 0.03, 0.004, 0.012, -0.08, 0.006, -0.002, 0.003))
    assert paper.version == 1 and richest.version == 2
    return {"paper": paper, "richest": richest, "none": None}


#: Boot-time zero variants measured with the richest calibration.
ZEROS = {
    "richest_zero_pending": ZeroConfig(settle_s=0.0, window_s=1.0, max_std_dps=1e-6,
                                       deadline_s=86400.0),
    "richest_zero_done": ZeroConfig(settle_s=0.0, window_s=1.0, max_std_dps=100.0),
}


def frames(n_rate: int, seed: int, temperature_period_s: float) -> list[can.Message]:
    rng = np.random.default_rng(seed)
    t = np.arange(n_rate) / 1000.0
    temp = 20.0 + 10.0 * np.sin(2 * np.pi * t / max(float(t[-1]), 1.0))  # heats and cools
    rates = {a: 0.1 + 0.01 * rng.standard_normal(n_rate) for a in "xyz"}
    run = Run("bench-effects", t, temp, rates,
              metadata={"temperature_period_s": str(temperature_period_s)})
    return list(frames_from_run(run, encoder=FrameEncoder(), t0_s=1_700_000_000.0))


def trial(msgs: list[can.Message], cal: Calibration | None,
          zero: ZeroConfig | None = None) -> float:
    pipe = Pipeline(FrameDecoder(), _Discard(), calibration=cal, zero=zero)
    process = pipe.process
    t0 = time.process_time()
    for m in msgs:
        process(m, 1_700_000_000.0)
    cpu = time.process_time() - t0
    c = pipe.counters()
    assert c.frames_published == len(msgs), c  # everything went through, nothing dropped
    if zero is not None:  # the variant is in the state it claims to measure
        z = pipe.compensation.zero
        assert z is not None and z.status.name == ("PENDING" if zero.max_std_dps < 1e-3
                                                   else "DONE"), z.status
    return cpu


def measure(msgs: list[can.Message], cals: dict[str, Calibration | None],
            rounds: int) -> dict[str, Any]:
    temp_id = FrameEncoder().layout.temperature.frame_id
    n_temp = sum(m.arbitration_id == temp_id for m in msgs)
    cpu: dict[str, list[float]] = {k: [] for k in (*cals, *ZEROS)}
    for _ in range(rounds):
        for name, cal in cals.items():
            cpu[name].append(trial(msgs, cal))
        for name, zero in ZEROS.items():
            cpu[name].append(trial(msgs, cals["richest"], zero))
    med = {k: statistics.median(v) for k, v in cpu.items()}
    return {
        "frames": len(msgs), "temperature_frames": n_temp, "rounds": rounds, "cpu_s": cpu,
        "us_per_frame_median": {k: 1e6 * v / len(msgs) for k, v in med.items()},
        # what a calibration adds per temperature frame over the no-calibration floor
        "compensation_us_per_temperature_frame": {
            k: 1e6 * (med[k] - med["none"]) / n_temp for k in ("paper", "richest")},
        "ratio_richest_to_paper_per_frame": med["richest"] / med["paper"],
        **{f"ratio_{k}_to_paper_per_frame": med[k] / med["paper"] for k in ZEROS},
        "ratio_richest_to_paper_per_round": [r / p for r, p in zip(cpu["richest"], cpu["paper"],
                                                                   strict=True)],
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--rate-frames", type=int, default=100_000, help="rate frames per trial")
    p.add_argument("--rounds", type=int, default=7, help="interleaved rounds (7)")
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args(argv)
    cals = calibrations()
    out: dict[str, Any] = {"benchmark": "effects_cost"}
    # the daemon's stream (10 Hz temperature: 1 % of the frames), and a temperature-heavy
    # one (a temperature frame with every rate frame) that isolates the compensation
    for name, period in (("stream_1khz_10hz", 0.1), ("temperature_heavy", 0.0)):
        n = a.rate_frames if period else a.rate_frames // 4
        out[name] = r = measure(frames(n, a.seed, period), cals, a.rounds)
        us, comp = r["us_per_frame_median"], r["compensation_us_per_temperature_frame"]
        print(f"{name}: µs/frame (median of {a.rounds}): paper {us['paper']:.2f}, richest "
              f"{us['richest']:.2f}, none {us['none']:.2f}; richest/paper "
              f"{r['ratio_richest_to_paper_per_frame']:.3f}; added per temperature frame: "
              f"paper {comp['paper']:.1f} µs, richest {comp['richest']:.1f} µs; with a zero "
              + ", ".join(f"{k} {us[k]:.2f} ({r[f'ratio_{k}_to_paper_per_frame']:.3f})"
                          for k in ZEROS), file=sys.stderr)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
