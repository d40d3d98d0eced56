"""Test helpers for the streaming path: frames from a run, a recording sink, ports.

Ports, without races against other processes (benchmarks, parallel suites):

* where a test owns the zenoh listener, listen on ``tcp/127.0.0.1:0`` and read the
  port the kernel bound back from the session's admin space
  (:func:`open_ephemeral`, :func:`listen_locators`);
* where a port must be chosen before something else opens it (the daemon's
  config), :func:`free_port` picks from a per-process random stretch of the ports
  *below* the kernel's ephemeral range (which ``bind(0)``, ``:0`` listeners and
  outgoing connections use), and :func:`retry_on_address_in_use` repeats the
  whole open with a fresh port when it still loses the race;
* where a test needs a port that nobody listens on, :func:`dead_port` holds one
  bound (never listening) for the duration: connections to it are refused.
"""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import can
import numpy as np
import pytest
import zenoh

from gyrotherm.analysis._effects import BASE_COLUMNS, ExtendedModel
from gyrotherm.analysis._to_calibration import calibration_from_models
from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, RateSample, Run, SignalMap, TemperatureSample
from gyrotherm.compensation import Calibration, RunFeatures, Scaling, ValidRange, features
from gyrotherm.daemon import Daemon, RunSummary, parse_config


def run_frames(run: Run, encoder: FrameEncoder, *, period_s: float = 0.0) -> Iterator[can.Message]:
    """Temperature frame (when due, as the offline estimator feeds rows) then rate frame."""
    last = -1e18
    for i, t in enumerate(run.time_s.tolist()):
        if t - last >= period_s - 1e-9:
            last = t
            yield encoder.encode_temperature(TemperatureSample(t, float(run.temperature_c[i])))
        r = run.rates_dps
        yield encoder.encode_rate(RateSample(t, float(r["x"][i]), float(r["y"][i]),
                                             float(r["z"][i])))


class RecordingSink:
    def __init__(self) -> None:
        self.rates: list[bytes] = []
        self.states: list[bytes] = []

    def put_rate(self, payload: bytes) -> None:
        self.rates.append(payload)

    def put_state(self, payload: bytes) -> None:
        self.states.append(payload)


T = TypeVar("T")

_LOWEST_PORT = 10_000
_handed_out: set[int] = set()
_rng = random.Random(os.getpid())  # per process: parallel runs start far apart


def _ephemeral_low() -> int:
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32_768  # the Linux default


def _bindable(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind(("127.0.0.1", port))  # no SO_REUSEADDR: TIME_WAIT counts as taken
        except OSError:
            return False
    return True


def free_port() -> int:
    """A loopback TCP port that is free now, not yet handed out by this process.

    Chosen from a per-process random start in [10000, start of the ephemeral
    range), so it cannot collide with ports the kernel assigns to ``bind(0)``
    callers or to outgoing connections. Still a check-then-use: open with
    :func:`retry_on_address_in_use` when the port is taken in between.
    """
    low, high = _LOWEST_PORT, max(_ephemeral_low(), _LOWEST_PORT + 1000)
    span = high - low
    start = _rng.randrange(span)
    for k in range(span):
        port = low + (start + k) % span
        if port not in _handed_out and _bindable(port):
            _handed_out.add(port)
            return port
    raise RuntimeError(f"no free loopback port in [{low}, {high})")


def is_address_in_use(exc: BaseException) -> bool:
    """True when ``exc`` (or an exception it was raised from) reports a port in use."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno == 98:
            return True
        if "address already in use" in str(seen).lower():
            return True
        seen = seen.__cause__
    return False


def retry_on_address_in_use(open_on: Callable[[int], T], *, attempts: int = 8) -> T:
    """``open_on(free_port())``, again with a fresh port when the port was taken meanwhile.

    Any other error, or the last "address in use", propagates.
    """
    for attempt in range(attempts):
        try:
            return open_on(free_port())
        except Exception as exc:
            if attempt == attempts - 1 or not is_address_in_use(exc):
                raise
    raise AssertionError("unreachable")  # pragma: no cover


@contextmanager
def dead_port() -> Iterator[int]:
    """A loopback port that is bound but never listens: connecting to it is refused."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port: int = holder.getsockname()[1]
        yield port


@contextmanager
def cli_process(*args: str) -> Iterator[subprocess.Popen[str]]:
    """``python -m gyrotherm ARGS`` with text pipes and faulthandler on; killed on the
    way out if it still runs."""
    proc = subprocess.Popen([sys.executable, "-m", "gyrotherm", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def stdout_after_sigterm(proc: subprocess.Popen[str], timeout_s: float) -> str:
    """SIGTERM, then the process's stdout once it exits; if it does not within
    ``timeout_s``, SIGABRT and a test failure that shows every thread's stack."""
    proc.send_signal(signal.SIGTERM)
    try:
        stdout, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        pytest.fail(f"no exit after SIGTERM:\n{proc.communicate(timeout=timeout_s)[1]}")
    return stdout


def stop_process(proc: subprocess.Popen[Any], timeout_s: float = 10.0) -> None:
    """SIGTERM a helper process (a router), SIGKILL it if it has not exited in time."""
    proc.terminate()
    try:
        proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout_s)


def enable_adminspace(config: zenoh.Config) -> zenoh.Config:
    """Let the session answer its own read-only admin queries (``@/<zid>/**``)."""
    config.insert_json5(
        "adminspace", json.dumps({"enabled": True, "permissions": {"read": True, "write": False}})
    )
    return config


def listen_locators(session: zenoh.Session, *, timeout_s: float = 10.0) -> list[str]:
    """The locators ``session`` actually listens on (ports resolved), from its admin space.

    The session's config must have gone through :func:`enable_adminspace`.
    """
    zid = str(session.zid())
    for reply in session.get(f"@/{zid}/*", timeout=timeout_s):
        ok = reply.ok
        if ok is not None and str(ok.key_expr) in (f"@/{zid}/peer", f"@/{zid}/router"):
            locators = json.loads(ok.payload.to_string())["locators"]
            return [str(loc) for loc in locators]
    raise AssertionError(f"session {zid} did not report its locators (adminspace enabled?)")


def open_ephemeral(config: zenoh.Config, *, timeout_s: float = 10.0) -> tuple[zenoh.Session, str]:
    """Open ``config`` (listening on one ``<proto>/127.0.0.1:0`` endpoint); return the
    session and the endpoint it really listens on, e.g. ``tcp/127.0.0.1:41977``."""
    listen = json.loads(config.get_json("listen/endpoints"))
    if isinstance(listen, dict):
        listen = listen.get(json.loads(config.get_json("mode")), [])
    assert len(listen) == 1 and listen[0].endswith("127.0.0.1:0"), listen
    proto = listen[0].split("/", 1)[0]
    session = zenoh.open(enable_adminspace(config))
    try:
        found = [loc for loc in listen_locators(session, timeout_s=timeout_s)
                 if loc.startswith(f"{proto}/127.0.0.1:")]  # fmt: skip
        assert len(found) == 1, f"expected one {proto}/127.0.0.1 locator, got {found}"
        assert not found[0].endswith(":0")
    except BaseException:
        session.close()
        raise
    return session, found[0]


#: A user's own gyro (tests of DBC-driven code): big-endian 12/16-bit rates in an
#: extended-id frame, an IEEE-float temperature, no counter and no CRC.
USER_DBC = """\
VERSION ""
NS_ :
BS_:
BU_: Imu Host
BO_ 2566852609 ImuRates: 6 Imu
 SG_ WX : 7|12@0- (0.05,0) [-100|100] "deg/s" Host
 SG_ WY : 11|12@0- (0.05,0) [-100|100] "deg/s" Host
 SG_ WZ : 31|16@0- (0.01,2) [-300|300] "deg/s" Host
BO_ 928 ImuTemp: 4 Imu
 SG_ TDie : 0|32@1- (1,0) [-40|125] "degC" Host
SIG_VALTYPE_ 928 TDie : 1;
"""
USER_SIGNAL_MAP = SignalMap(
    rate_message="ImuRates", rate_x_signal="WX", rate_y_signal="WY", rate_z_signal="WZ",
    temperature_message="ImuTemp", temperature_signal="TDie",
)



def offline_bias(calibration: Calibration, time_s: np.ndarray, temperature_c: np.ndarray,
                 delta_t_c: np.ndarray) -> dict[str, np.ndarray]:
    """Per axis, the bias offline evaluation gives for one estimator output series
    starting at power-on: version 1 the polynomial (:meth:`Calibration.bias_series`),
    version 2 a fresh :meth:`Calibration.compensator`'s series with t_on = t − t[0]
    (0 for an axis the calibration does not have)."""
    t = np.asarray(time_s, dtype=np.float64)
    if calibration.version == 1:
        return {a: calibration.bias_series(a, temperature_c, delta_t_c)[0]
                if a in calibration.axes else np.zeros(len(t)) for a in "xyz"}
    out = calibration.compensator().series(t, np.asarray(temperature_c),
                                           np.asarray(delta_t_c), t - t[0])
    return {a: out.bias_dps[a] if a in out.bias_dps else np.zeros(len(t)) for a in "xyz"}


def assert_offline_compensation(
    rates_dps: list[tuple[float, float, float]], run: Run, calibration: Calibration
) -> RunFeatures:
    """The daemon's corrected rates (one per row, x y z, °/s) equal offline
    compensation of ``run``: raw − F(T, ΔT) with T and ΔT from :func:`features`
    (to 1e-9 °/s); with effects (version 2) the compensator's series from the run's
    first row as power-on (:func:`offline_bias`). Returns the offline features."""
    got = np.array(rates_dps)
    assert got.shape == (len(run), 3), got.shape
    offline = features(run, calibration.estimator)
    bias = offline_bias(calibration, offline.time_s, offline.temperature_c, offline.delta_t_c)
    for j, axis in enumerate("xyz"):
        np.testing.assert_allclose(got[:, j], run.rates_dps[axis] - bias[axis], atol=1e-9)
    return offline


EFFECTS_SCALING = Scaling(t_ref_c=15.0, t_scale_c=35.0, dt_scale_c=8.0)
ALL_EFFECTS = {"thermal_lag": 75.0, "hysteresis": 0.35, "warmup": 400.0, "cubic": 0.0,
               "gradient_quadratic": 0.0, "drift": 0.0}
EFFECTS_COLUMNS = (*BASE_COLUMNS, "hysteresis", "warmup", "cubic", "gradient_quadratic",
                   "drift")


def make_v2(stream_calibration: Calibration, *, scale: float = 1.0,
            t_on_max_s: float = 7200.0, y_effects: bool = True) -> Calibration:
    """x: every effect; y: thermal_lag + warmup (or none); z: the paper polynomial."""
    x = ExtendedModel(EFFECTS_SCALING, ALL_EFFECTS, EFFECTS_COLUMNS,
                      tuple(scale * c for c in (0.02, -0.05, 0.03, 0.004, 0.012, -0.08,
                                                0.006, -0.002, 0.003)), intercept_dps=0.7)
    y = (ExtendedModel(EFFECTS_SCALING, {"thermal_lag": 200.0, "warmup": 900.0},
                       (*BASE_COLUMNS, "warmup"), (-0.01, 0.04, 0.02, -0.003, 0.05),
                       intercept_dps=-0.2) if y_effects else
         ExtendedModel(EFFECTS_SCALING, {}, BASE_COLUMNS, (-0.01, 0.04, 0.02, -0.003),
                       intercept_dps=-0.2))
    z = ExtendedModel(EFFECTS_SCALING, {}, BASE_COLUMNS, (0.005, 0.01, -0.02, 0.001),
                      intercept_dps=0.1)
    return calibration_from_models({"x": x, "y": y, "z": z},
                                   estimator=stream_calibration.estimator,
                                   t_on_max_s=t_on_max_s,
                                   valid_range=ValidRange(-60.0, 90.0, -500.0, 500.0),
                                   provenance={"method": "by hand"})


_DAEMON_TIMEOUT_S = 20.0


def run_daemon_in_process(cfg: dict[str, object], tmp_path: Path, frames: list,
                          channel: str, port: int, n_rows: int) -> tuple[list, list, RunSummary]:
    """A Daemon of ``cfg`` in a thread (virtual CAN ``channel``, Zenoh on ``port``):
    ``frames`` sent, the rate and state messages received until ``n_rows`` of each,
    then stopped; returns them with the run summary."""
    daemon = Daemon(parse_config(cfg, base_dir=tmp_path))
    result: dict[str, RunSummary] = {}
    thread = threading.Thread(target=lambda: result.update(s=daemon.run()), daemon=True)
    thread.start()
    assert daemon.ready.wait(_DAEMON_TIMEOUT_S)
    try:
        with Subscriber("car", "imu0", connect=[f"tcp/127.0.0.1:{port}"]) as sub, \
                open_bus(interface="virtual", channel=channel) as bus:
            assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=_DAEMON_TIMEOUT_S)
            for msg in frames:
                bus.send(msg)
            assert sub.wait_for(lambda s: s.rate.received >= n_rows
                                and s.state.received >= n_rows, timeout_s=_DAEMON_TIMEOUT_S)
            rates = list(sub.rates(timeout_s=0.5))
            states = list(sub.states(timeout_s=0.5))
    finally:
        daemon.stop()
        thread.join(_DAEMON_TIMEOUT_S)
    assert not thread.is_alive() and "s" in result
    return rates, states, result["s"]


def restart_setup(tmp_path: Path, cal_path: Path, run: Run, prefix: str,
                  **extra: object) -> tuple[list[can.Message], str, int, dict[str, object]]:
    """For a daemon stopped and started again on one run: the run's frames, a fresh
    virtual channel and Zenoh port, and a config with ``state_dir`` (created) and
    ``calibration`` (``extra``: more top-level keys, e.g. ``zero``)."""
    import uuid

    channel, port = f"{prefix}-{uuid.uuid4().hex[:8]}", free_port()
    cfg: dict[str, object] = {
        "vehicle": "car", "sensor": "imu0", "calibration": str(cal_path),
        "state_dir": "state", "health_period_s": 0.2, **extra,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}
    (tmp_path / "state").mkdir()
    return list(run_frames(run, FrameEncoder())), channel, port, cfg
