"""Time ``diagnose`` on seven 2-hour runs at 10 Hz; print one JSON line.

    .venv/bin/python bench/diagnose_speed.py [--no-simulation]

Runs come from the independent generator (gyrotherm.analysis.synth_runs, one
effect injected); generation is not timed, reading CSV is not included.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time

from gyrotherm.analysis import SynthConfig, diagnose, synth_runs


def main() -> None:
    simulate = "--no-simulation" not in sys.argv
    runs, _ = synth_runs(SynthConfig(duration_s=7200.0, rate_hz=10.0,
                                     effects={"hysteresis": {}}), n_runs=7, seed=11)
    start = time.perf_counter()
    result = diagnose(runs, simulate=simulate)
    elapsed = time.perf_counter() - start
    print(json.dumps({
        "benchmark": "diagnose_7x2h_10hz",
        "runs": len(runs),
        "rows": sum(len(r) for r in runs),
        "simulation": simulate,
        "seconds": round(elapsed, 2),
        "found": [f.effect for f in result.findings],
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
