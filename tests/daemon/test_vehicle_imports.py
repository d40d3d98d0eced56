"""The vehicle path loads no offline stack: no scipy, filterpy, matplotlib, pandas, flight-log
libraries, simulator or analysis (issue 22, "a lean vehicle daemon").

A fresh interpreter imports what ``gyrotherm run`` imports (the CLI entry, its parser, the
``run`` command's module, the daemon, the codecs, the estimators, the compensation, the
bus, the Zenoh helpers) and then *runs* the daemon's pipeline in-process: CAN frames of a
simulated chamber run (rows handed over as JSON) → decode → Kalman T/ΔT → compensation →
wire payloads, so that whatever the per-frame path imports when it runs is in its module
table too. The offline parts of the vehicle packages (run files, candump logs, wire
decoding, fitting, the series estimator, the flight-log readers, the offline commands)
stay out as well: the packages' ``__init__`` load them on first use. The parent checks
the corrected rates against offline compensation (to 1e-9 °/s: the child really ran the
estimator) and the module table against the offline list.

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

import numpy as np
import pytest

import gyrotherm
import gyrotherm.codecs
from gyrotherm.codecs import Run, decode_rate
from gyrotherm.compensation import Calibration
from streamkit import assert_offline_compensation

TIMEOUT_S = 120.0
SRC = Path(gyrotherm.__file__).resolve().parent

#: Never loaded on the vehicle path (a module or any of its submodules).
OFFLINE = ("scipy", "filterpy", "matplotlib", "pandas", "gyrotherm.analysis", "gyrotherm.sim",
           "gyrotherm.client", "pyulog", "pymavlink", "rosbags", "mcap")

#: Offline modules inside the vehicle packages, lazy since issue 22: the daemon needs none.
OFFLINE_PARTS = ("gyrotherm.readers", "gyrotherm.cli._offline", "gyrotherm.cli._diagnose",
                 "gyrotherm.cli._demo", "gyrotherm.cli._export", "gyrotherm.cli._import",
                 "gyrotherm.codecs._runfile", "gyrotherm.codecs._candump",
                 "gyrotherm.codecs._wire_decode", "gyrotherm.compensation._fit",
                 "gyrotherm.estimators._series",
                 # learning on the vehicle: loaded only with [learn] (this child has none)
                 "gyrotherm.daemon._learner", "gyrotherm.daemon._learn_store",
                 "gyrotherm.compensation._learn", "gyrotherm.compensation._learnstate",
                 # the consistency signal: several IMUs only (this child has one)
                 "gyrotherm.daemon._consistency", "gyrotherm.codecs._wire_consistency")

VEHICLE_CHILD = textwrap.dedent("""
    import json, sys

    from gyrotherm.cli import main, parse_args  # the console script's entry point
    args = parse_args(["run", "--config", "gyrotherm.toml"])  # as main() parses it
    __import__(args.func.__module__)  # what `gyrotherm run` imports before it starts
    import gyrotherm._zenoh, gyrotherm.bus, gyrotherm.codecs, gyrotherm.compensation
    import gyrotherm.daemon, gyrotherm.estimators
    from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, TemperatureSample
    from gyrotherm.compensation import load_calibration
    from gyrotherm.daemon import Pipeline
    from gyrotherm.estimators import TemperatureEstimator

    with open(sys.argv[1]) as f:
        rows = json.load(f)  # [time_s, temperature_c, x, y, z] per row
    cal = load_calibration(sys.argv[2])

    class Sink:
        def __init__(self):
            self.rates = []
        def put_rate(self, payload):
            self.rates.append(bytes(payload).hex())
        def put_state(self, payload):
            pass

    sink, enc = Sink(), FrameEncoder()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal)
    for t, temp, x, y, z in rows:
        pipe.process(enc.encode_temperature(TemperatureSample(t, temp)), 1.0e9)
        pipe.process(enc.encode_rate(RateSample(t, x, y, z)), 1.0e9)
    engine = TemperatureEstimator().engine
    print(json.dumps({"modules": sorted(sys.modules), "engine": engine, "rates": sink.rates}))
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


def _matches(name: str, prefixes: tuple[str, ...] = OFFLINE) -> list[str]:
    return [p for p in prefixes if name == p or name.startswith(p + ".")]


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
    rows = np.column_stack([run.time_s, run.temperature_c,
                            *(run.rates_dps[a] for a in "xyz")]).tolist()
    rows_path = d / "rows.json"
    rows_path.write_text(json.dumps(rows), encoding="utf-8")  # repr floats: exact
    return run, rows_path, stream_calibration.save(d / "cal.json")


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
    offline = {m: _matches(m) + _matches(m, OFFLINE_PARTS) for m in modules}
    assert not {m: p for m, p in offline.items() if p}, "offline modules on the vehicle path"
    # ... and it computed the real thing: the daemon's corrected rates equal offline
    # compensation (the offline features come from the filter's float loop, checked
    # against filterpy in tests/estimators)
    payloads = out["rates"]
    assert isinstance(payloads, list) and len(payloads) == len(run)
    rates = [decode_rate(bytes.fromhex(p)).rate_dps for p in payloads]
    assert_offline_compensation(rates, run, stream_calibration)


def test_control_the_filterpy_engine_does_load_filterpy_and_scipy() -> None:
    out = _child(CONTROL_CHILD)
    modules = out["modules"]
    assert isinstance(modules, list) and out["engine"] == "filterpy"
    loaded = {p for m in modules for p in _matches(m)}
    assert {"filterpy", "scipy"} <= loaded
    assert not loaded & {"gyrotherm.sim", "gyrotherm.analysis"}


LAZY_PACKAGES = ("gyrotherm.codecs", "gyrotherm.compensation", "gyrotherm.estimators")


def test_the_public_api_keeps_every_name() -> None:
    """The packages whose offline names load lazily still export every name of their
    ``__all__``, as the defining module's object, through attribute access, ``from ...
    import`` and ``import *``, and list them in ``dir()``. In a fresh interpreter, so the
    first access is the lazy one."""
    code = textwrap.dedent("""
        import importlib, json, sys
        out = {}
        for name in sys.argv[1:]:
            pkg = importlib.import_module(name)
            ns = {}
            exec(f"from {name} import *", ns)
            lazy = dict(pkg._LAZY)
            out[name] = {
                "all": sorted(pkg.__all__),
                "star": sorted(k for k in ns if not k.startswith("__")),
                "dir_missing": sorted(set(pkg.__all__) - set(dir(pkg))),
                "lazy_same": all(getattr(pkg, n) is getattr(importlib.import_module(m), n)
                                 for n, m in lazy.items()),
                "lazy_in_all": sorted(set(lazy) - set(pkg.__all__)),
            }
        print(json.dumps(out))
    """)
    out = _child(code, *LAZY_PACKAGES)
    for name in LAZY_PACKAGES:
        got = out[name]
        assert isinstance(got, dict)
        assert got["star"] == got["all"] and len(got["all"]) > 3, name
        assert got["dir_missing"] == [] and got["lazy_same"] and got["lazy_in_all"] == [], name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = gyrotherm.codecs.nope  # type: ignore[attr-defined]
