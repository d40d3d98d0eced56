"""What the vehicle path loads: ``gyrotherm run`` imports the daemon path, nothing offline.

* ``gyrotherm run --config FILE`` in a fresh interpreter, driven like systemd drives
  it (``NOTIFY_SOCKET``, READY=1, frames through the pipeline to a subscriber,
  SIGTERM), then its ``sys.modules``: no simulator, no analysis, no plotting, no
  client library, no scipy, no filterpy.
* Layering: ``gyrotherm.daemon``, ``gyrotherm.bus`` and ``gyrotherm.client`` never
  reach ``gyrotherm.sim`` (nor ``gyrotherm.analysis``): statically, through every
  ``gyrotherm`` import in every reachable module (function-level imports included,
  ``if TYPE_CHECKING:`` blocks excluded), and at run time in a fresh interpreter.

No clock is asserted here; bench/footprint.py measures the times and memory.
"""

from __future__ import annotations

import ast
import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

import gyrotherm
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder
from gyrotherm.compensation import Calibration, features, fit
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim import GyroParams, SocketcandServer, chamber_runs
from gyrotherm.sim._stream import frames_from_run, play
from streamkit import free_port

TIMEOUT_S = 60.0
SRC = Path(gyrotherm.__file__).resolve().parent
VEHICLE_PACKAGES = ("gyrotherm.daemon", "gyrotherm.bus", "gyrotherm.client")

#: Never on the ``gyrotherm run`` path (a module or any of its submodules).
NOT_ON_RUN_PATH = (
    "gyrotherm.sim",  # the simulator (and scipy.signal through sim._chamber)
    "gyrotherm.analysis",  # the offline diagnosis (matplotlib in its report)
    "gyrotherm.client",  # the subscriber library: the daemon publishes, never subscribes
    "matplotlib",
    "scipy",  # scipy.signal through the simulator, scipy.stats through filterpy (issue 22)
    "filterpy",  # the estimator's reference engine only; the daemon's runs in floats
)
#: Never reached from the vehicle packages.
NOT_FROM_VEHICLE = ("gyrotherm.sim", "gyrotherm.analysis")

# The child: the real CLI entry point, then its module table as one JSON line.
CHILD = textwrap.dedent("""
    import json, sys
    from gyrotherm.cli import main
    code = main(sys.argv[1:])
    print("MODULES " + json.dumps(sorted(sys.modules)), flush=True)
    raise SystemExit(code)
""")


def _matches(name: str, prefixes: tuple[str, ...]) -> list[str]:
    return [p for p in prefixes if name == p or name.startswith(p + ".")]


def _child_env(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC.parent), *filter(None, [
        env.get("PYTHONPATH")])])  # this tree's gyrotherm, whatever the install
    env.update(extra)
    return env


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> Path:
    runs = chamber_runs([5, 20, 60], seed=8, rate_hz=1.0, hold_s=1200)
    est = EstimatorConfig(tau_s=GyroParams().tau_s)
    cal: Calibration = fit([features(r, est) for r in runs], "paper", estimator=est)
    return cal.save(tmp_path_factory.mktemp("footprint") / "cal.json")


@pytest.fixture
def notify_socket(tmp_path: Path) -> Iterator[tuple[socket.socket, str]]:
    path = str(tmp_path / "notify.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(path)
        sock.settimeout(TIMEOUT_S)
        yield sock, path


def _wait_for_ready(sock: socket.socket, proc: subprocess.Popen[str]) -> None:
    """Wait for READY=1, then keep reading the socket as systemd does (a full queue,
    net.unix.max_dgram_qlen datagrams, would block the daemon's next notification)."""
    got: list[str] = []
    while True:
        try:
            data = sock.recv(4096).decode()
        except TimeoutError:
            pytest.fail(f"no READY=1 within {TIMEOUT_S} s (exit {proc.poll()}): {got}")
        got.append(data)
        if "READY=1" in data.splitlines():
            break

    def drain() -> None:
        while sock.fileno() != -1:  # until the fixture closes it
            try:
                sock.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return

    sock.settimeout(0.2)
    threading.Thread(target=drain, daemon=True).start()


def test_run_path_loads_no_offline_modules(
    tmp_path: Path, calibration: Path, notify_socket: tuple[socket.socket, str]
) -> None:
    sock, notify_path = notify_socket
    run = chamber_runs([5], seed=2, rate_hz=1.0, hold_s=60)[0].slice(0, 200)
    zport = free_port()
    with SocketcandServer(host="127.0.0.1", port=0) as server:
        config = tmp_path / "gyrotherm.toml"
        config.write_text(textwrap.dedent(f"""
            vehicle = "fp"
            sensor = "imu0"
            calibration = "{calibration}"
            health_period_s = 0.2
            [can]
            interface = "socketcand"
            host = "127.0.0.1"
            port = {server.port}
            channel = "vcan0"
            [zenoh]
            listen = ["tcp/127.0.0.1:{zport}"]
        """))
        proc = subprocess.Popen(
            [sys.executable, "-c", CHILD, "run", "--config", str(config)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=_child_env(NOTIFY_SOCKET=notify_path))
        stderr: list[str] = []
        assert proc.stderr is not None
        threading.Thread(target=lambda: stderr.extend(proc.stderr or []), daemon=True).start()
        try:
            _wait_for_ready(sock, proc)
            assert server.wait_for_clients(1, TIMEOUT_S)
            # frames through decode → Kalman T/ΔT → compensation → Zenoh, so that
            # whatever the pipeline imports when it runs is in the child's table too
            with Subscriber("fp", "imu0", connect=[f"tcp/127.0.0.1:{zport}"]) as sub:
                assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
                played = play(frames_from_run(run, encoder=FrameEncoder()), server, speed=0)
                assert server.flush(TIMEOUT_S)
                assert sub.wait_for(lambda s: s.rate.received >= played.rate_frames,
                                    timeout_s=TIMEOUT_S), sub.stats()
            proc.send_signal(signal.SIGTERM)
            out, _ = proc.communicate(timeout=TIMEOUT_S)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 0, (out, stderr)
    assert played.rate_frames > 0
    lines = [x for x in out.splitlines() if x.startswith("MODULES ")]
    assert len(lines) == 1, out
    modules: list[str] = json.loads(lines[0].removeprefix("MODULES "))
    # the child ran this tree's daemon path (a control: the table is the real one)
    for needed in ("gyrotherm.cli._run", "gyrotherm.daemon._service",
                   "gyrotherm.estimators._temperature", "zenoh", "can", "msgpack"):
        assert needed in modules, needed
    loaded = {m: _matches(m, NOT_ON_RUN_PATH) for m in modules}
    assert not {m: p for m, p in loaded.items() if p}, "offline modules on the run path"


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _runtime_imports(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement, at any depth, except under ``if TYPE_CHECKING:``."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                yield from _runtime_imports(ast.Module(body=[child], type_ignores=[]))
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        yield from _runtime_imports(node)


def _module_files() -> dict[str, Path]:
    out = {}
    for path in SRC.rglob("*.py"):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _with_parents(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[: i + 1]) for i in range(len(parts))]


def _import_graph() -> dict[str, set[str]]:
    """gyrotherm module → the gyrotherm modules (and their parent packages) it imports."""
    files = _module_files()
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        is_pkg = path.name == "__init__.py"
        deps: set[str] = set()
        for node in _runtime_imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:  # relative: resolve against this module's package
                    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    pkg = pkg[: len(pkg) - (node.level - 1)]
                    base = ".".join([*pkg, *([base] if base else [])])
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base
                           for a in node.names]
            for t in targets:
                if t == "gyrotherm" or t.startswith("gyrotherm."):
                    deps.update(p for p in _with_parents(t) if p in files)
        graph[mod] = deps - {mod}
    return graph


def _reachable(graph: dict[str, set[str]], start: str) -> dict[str, str | None]:
    """Modules reachable from ``start`` (and its submodules) → the module that imports it."""
    roots = [m for m in graph if m == start or m.startswith(start + ".")]
    seen: dict[str, str | None] = {r: None for r in roots}
    todo = list(roots)
    while todo:
        m = todo.pop()
        for d in graph.get(m, ()):
            if d not in seen:
                seen[d] = m
                todo.append(d)
    return seen


def _chain(seen: dict[str, str | None], m: str) -> str:
    path = [m]
    while (parent := seen[path[-1]]) is not None:
        path.append(parent)
    return " ← ".join(path)


def test_import_graph_sees_the_offline_commands_reach_the_simulator() -> None:
    """Control: the graph does find imports of gyrotherm.sim where they exist, including
    the function-level ones of the offline commands."""
    seen = _reachable(_import_graph(), "gyrotherm.cli._offline")
    assert "gyrotherm.sim" in seen
    assert "gyrotherm.analysis" in _reachable(_import_graph(), "gyrotherm.cli._diagnose")


@pytest.mark.parametrize("package", VEHICLE_PACKAGES)
def test_vehicle_packages_never_reach_the_simulator(package: str) -> None:
    seen = _reachable(_import_graph(), package)
    assert len(seen) > 3  # the package and what it uses
    bad = [_chain(seen, m) for m in seen if _matches(m, NOT_FROM_VEHICLE)]
    assert not bad, bad


def test_vehicle_packages_load_no_simulator_at_run_time() -> None:
    code = ("import json, sys\n" + "".join(f"import {p}\n" for p in VEHICLE_PACKAGES)
            + "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=TIMEOUT_S, env=_child_env(), check=True)
    modules: list[str] = json.loads(done.stdout)
    assert set(VEHICLE_PACKAGES) <= set(modules)
    assert not [m for m in modules if _matches(m, NOT_FROM_VEHICLE)]
