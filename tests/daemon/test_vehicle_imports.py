"""The vehicle path loads no offline stack: no scipy, filterpy, matplotlib, pandas, flight-log
libraries, simulator or analysis (issue 22, "a lean vehicle daemon").

A fresh interpreter imports what ``gyrotherm run`` imports (the CLI entry, its parser, the
``run`` command's module, the daemon, the codecs, the estimators, the compensation, the
bus, the Zenoh helpers) and then *runs* the daemon's pipeline in-process: CAN frames of a
simulated chamber run (read from a run file) → decode → Kalman T/ΔT → compensation →
wire payloads, so that whatever the per-frame path imports when it runs is in its module
table too. The parent checks the corrected rates against offline compensation (to 1e-9
°/s: the child really ran the estimator) and the module table against the offline list.

A control child builds the estimator on its filterpy engine: there, filterpy and scipy
*are* in the table (the check sees them when they are loaded).

No clock: bench/footprint.py measures the import time, time to READY and memory.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import gyrotherm
from gyrotherm.codecs import Run, write_run
from gyrotherm.compensation import Calibration
from streamkit import assert_offline_compensation

TIMEOUT_S = 120.0
SRC = Path(gyrotherm.__file__).resolve().parent

#: Never loaded on the vehicle path (a module or any of its submodules).
OFFLINE = ("scipy", "filterpy", "matplotlib", "pandas", "gyrotherm.analysis", "gyrotherm.sim",
           "gyrotherm.client", "pyulog", "pymavlink", "rosbags", "mcap")

VEHICLE_CHILD = textwrap.dedent("""
    import json, sys

    from gyrotherm.cli import build_parser, main  # the console script's entry point
    args = build_parser().parse_args(["run", "--config", "gyrotherm.toml"])
    __import__(args.func.__module__)  # what `gyrotherm run` imports before it starts
    import gyrotherm._zenoh, gyrotherm.bus, gyrotherm.codecs, gyrotherm.compensation
    import gyrotherm.daemon, gyrotherm.estimators
    from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, TemperatureSample
    from gyrotherm.codecs import decode_rate, read_run
    from gyrotherm.compensation import load_calibration
    from gyrotherm.daemon import Pipeline
    from gyrotherm.estimators import TemperatureEstimator

    run, cal = read_run(sys.argv[1]), load_calibration(sys.argv[2])

    class Sink:
        def __init__(self):
            self.rates = []
        def put_rate(self, payload):
            self.rates.append(payload)
        def put_state(self, payload):
            pass

    sink, enc = Sink(), FrameEncoder()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal)
    for i, t in enumerate(run.time_s.tolist()):
        pipe.process(enc.encode_temperature(TemperatureSample(t, float(run.temperature_c[i]))),
                     1.0e9)
        r = [float(run.rates_dps[a][i]) for a in "xyz"]
        pipe.process(enc.encode_rate(RateSample(t, *r)), 1.0e9)
    engine = TemperatureEstimator().engine
    print(json.dumps({"modules": sorted(sys.modules), "engine": engine,
                      "rates": [list(decode_rate(p).rate_dps) for p in sink.rates]}))
""")

CONTROL_CHILD = textwrap.dedent("""
    import json, sys
    import gyrotherm.daemon
    from gyrotherm.estimators import TemperatureEstimator
    est = TemperatureEstimator(engine="filterpy")
    est.update(0.0, 20.0)
    est.update(1.0, 20.1)
    print(json.dumps({"modules": sorted(sys.modules), "engine": est.engine, "rates": []}))
""")


def _matches(name: str) -> list[str]:
    return [p for p in OFFLINE if name == p or name.startswith(p + ".")]


def _child(code: str, *argv: str) -> dict[str, object]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(SRC.parent), *filter(None, [env.get("PYTHONPATH")])])  # this tree's gyrotherm
    done = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                          timeout=TIMEOUT_S, env=env, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    out: dict[str, object] = json.loads(done.stdout.splitlines()[-1])
    return out


@pytest.fixture(scope="module")
def files(short_runs: list[Run], stream_calibration: Calibration,
          tmp_path_factory: pytest.TempPathFactory) -> tuple[Run, Path, Path]:
    d = tmp_path_factory.mktemp("vehicle")
    run = short_runs[2].slice(0, 1500)  # 25 min of a 60-min heating run at 1 Hz
    return (run, write_run(run, d / "run.csv", exact=True),
            stream_calibration.save(d / "cal.json"))


def test_the_vehicle_path_loads_no_offline_module_and_runs(
    files: tuple[Run, Path, Path], stream_calibration: Calibration,
) -> None:
    run, run_path, cal_path = files
    out = _child(VEHICLE_CHILD, str(run_path), str(cal_path))
    modules = out["modules"]
    assert isinstance(modules, list)
    # the child ran this tree's vehicle path (a control: the table is the real one)
    for needed in ("gyrotherm.cli._run", "gyrotherm.daemon._service", "gyrotherm.daemon._pipeline",
                   "gyrotherm.estimators._temperature", "gyrotherm.compensation._compensator",
                   "gyrotherm.codecs._wire", "zenoh", "can", "cantools", "msgpack", "numpy"):
        assert needed in modules, needed
    assert out["engine"] == "python"
    offline = {m: _matches(m) for m in modules}
    assert not {m: p for m, p in offline.items() if p}, "offline modules on the vehicle path"
    # ... and it computed the real thing: the daemon's corrected rates equal offline
    # compensation (the offline features come from the filter's float loop, checked
    # against filterpy in tests/estimators)
    rates = out["rates"]
    assert isinstance(rates, list) and len(rates) == len(run)
    assert_offline_compensation([tuple(r) for r in rates], run, stream_calibration)


def test_control_the_filterpy_engine_does_load_filterpy_and_scipy() -> None:
    out = _child(CONTROL_CHILD)
    modules = out["modules"]
    assert isinstance(modules, list) and out["engine"] == "filterpy"
    loaded = {p for m in modules for p in _matches(m)}
    assert {"filterpy", "scipy"} <= loaded
    assert not loaded & {"gyrotherm.sim", "gyrotherm.analysis"}
