"""Time ``diagnose`` on seven 2-hour runs at 10 Hz; print one JSON line.

    .venv/bin/python bench/diagnose_speed.py [--no-simulation] [--candump] [--structures]
                                             [--power]

``--structures``: instead, four devices of the generalisation sweep whose diagnosis finds
an unexplained structure (a periodic bias in T and a saturating ΔT response at 0.125 °C, a
bias ∝ |ΔT| at 0.5 °C and at 1 °C; shapes-dev2 seeds 41–44, 3–4 runs of 6000 s), without
the simulator: what the structure's own checks cost (``not_told_from``, the replays).

``--power``: instead, three devices whose diagnosis names an effect in ΔT without a shape
note, so the shape check's power runs (replays with the effect's alternative shape, white
and, from round 11, coloured): |ΔT| named c·ΔT² at 1 °C (shapes-dev2 seed 48), the
catalogue's c·ΔT² and hysteresis at 0.5 °C (seed 1); 3 runs of 6000 s, without the simulator.

Runs come from the independent generator (gyrotherm.analysis.synth_runs, one
effect injected); generation is not timed, reading CSV is not included. With
``--candump`` the runs are first written as ``candump -l`` logs of the
shipped DBC's frames (not timed), and reading them back
(:func:`gyrotherm.codecs._candump_run.run_from_candump`: parse, decode, build
the run) is timed separately and included in ``seconds``.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from gyrotherm.analysis import SynthConfig, diagnose, synth_runs
from gyrotherm.codecs import FrameEncoder, Run, write_candump
from gyrotherm.codecs._candump_run import run_from_candump
from gyrotherm.sim import frames_from_run


def _via_candump(runs: list[Run], folder: Path) -> tuple[list[Run], float, int]:
    paths = []
    frames = 0
    for run in runs:
        path = folder / f"{run.name}.log"
        frames += write_candump(path, frames_from_run(run, encoder=FrameEncoder()))
        paths.append(path)
    start = time.perf_counter()
    out = [run_from_candump(p) for p in paths]
    return out, time.perf_counter() - start, frames


STRUCTURE_CASES = (  # (rate Hz, LSB °C, hold s, runs, shape, seed)
    (10.0, 0.125, 1.28, 4, "periodic_t", 41), (10.0, 0.125, 1.28, 4, "saturating_dt", 43),
    (50.0, 0.5, 1.0, 3, "abs_dt", 42), (10.0, 1.0, 1.3, 3, "abs_dt", 44))


Params = dict[str, dict[str, float]]
POWER_CASES: tuple[tuple[float, float, float, int, Params, Params, int], ...] = (
    # (rate Hz, LSB °C, hold s, runs, shapes, effects, seed)
    (10.0, 1.0, 1.3, 3, {"abs_dt": {}}, {}, 48),
    (50.0, 0.5, 1.0, 3, {}, {"gradient_quadratic": {}}, 1),
    (50.0, 0.5, 1.0, 3, {}, {"hysteresis": {}}, 1))


def _devices(name: str, cases: list[tuple[SynthConfig, Params, int, int]]) -> None:
    from gyrotherm.analysis.synth._variants import variant_runs

    seconds, found = [], []
    for cfg, shapes, n_runs, seed in cases:
        runs, _ = variant_runs(cfg, shapes=shapes, n_runs=n_runs, seed=seed)
        start = time.perf_counter()
        result = diagnose(runs, simulate=False)
        seconds.append(round(time.perf_counter() - start, 2))
        found.append([f.effect for f in result.findings]
                     + [f"unexplained:{u.variable}" for u in result.unexplained]
                     + [v.effect for v in result.not_resolvable if v.effect.startswith("shape:")])
    print(json.dumps({
        "benchmark": name, "seconds": round(sum(seconds), 2),
        "per_device_seconds": seconds, "found": found, "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }))


def main() -> None:
    if "--structures" in sys.argv:
        _devices("diagnose_structures_4_devices", [
            (SynthConfig(duration_s=6000.0, rate_hz=r, readout_lsb_c=q, readout_period_s=h),
             {shape: {}}, n, seed) for r, q, h, n, shape, seed in STRUCTURE_CASES])
        return
    if "--power" in sys.argv:
        _devices("diagnose_shape_power_3_devices", [
            (SynthConfig(duration_s=6000.0, rate_hz=r, readout_lsb_c=q, readout_period_s=h,
                         effects=effects), shapes, n, seed)
            for r, q, h, n, shapes, effects, seed in POWER_CASES])
        return
    simulate = "--no-simulation" not in sys.argv
    candump = "--candump" in sys.argv
    runs, _ = synth_runs(SynthConfig(duration_s=7200.0, rate_hz=10.0,
                                     effects={"hysteresis": {}}), n_runs=7, seed=11)
    extra: dict[str, float | int] = {}
    read_s = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        if candump:
            runs, read_s, frames = _via_candump(runs, Path(tmp))
            extra = {"candump_frames": frames, "candump_read_seconds": round(read_s, 2)}
        start = time.perf_counter()
        result = diagnose(runs, simulate=simulate)
        elapsed = time.perf_counter() - start + read_s
    print(json.dumps({
        "benchmark": "diagnose_7x2h_10hz" + ("_candump" if candump else ""),
        "runs": len(runs),
        "rows": sum(len(r) for r in runs),
        "simulation": simulate,
        "seconds": round(elapsed, 2),
        **extra,
        "found": [f.effect for f in result.findings],
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
