"""README.md "A short tour", run as written (smaller runs, robust ports), so it cannot rot.

The commands are read from the README's ``sh`` blocks, not copied here. A few
substitutions make them small and give them ports nobody else holds; each must
match the README (or the example config) exactly once, so a README change that
this test does not know about fails here instead of silently going untested.
Commands ending in ``&`` run in the background; ``kill %1 %2`` stops them.

As when the block is pasted into a shell, the streaming commands start one right
after the other, waiting on nothing: the simulator, the daemon (which waits for
the simulator's port) and ``listen`` (which waits for the daemon) come up in
whatever order they manage.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import IO

import pytest

from streamkit import free_port, retry_on_address_in_use

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
EXAMPLE_CONFIG = ROOT / "examples" / "bench-socketcand.toml"
STEP_TIMEOUT_S = 180.0  # generous bound per command on 2 loaded cores; not a speed check

#: README text → what the test runs instead (each must occur exactly once in the tour).
SMALLER = {
    "--heating-min 5 10 20 30 40 50 60": "--heating-min 5 10 20 --rate-hz 1 --hold-s 600",
    "--heating-min 60 --validation": "--heating-min 60 --validation --rate-hz 1 --hold-s 600",
    "--count 50": "--count 20 --timeout-s 120",
}
ZENOH_README = "tcp/127.0.0.1:7447"
SIM_PORT_README = "--port 29536"
SOCKETCAND_CONFIG = "port = 29536"
ZENOH_CONFIG = 'listen = ["tcp/127.0.0.1:7447"]'


def tour_commands() -> list[str]:
    """The shell commands of README.md's "A short tour" section, comments removed."""
    text = README.read_text(encoding="utf-8")
    section = text.split("\n## A short tour\n", 1)[1].split("\n## ", 1)[0]
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        for line in block.splitlines():
            command = re.sub(r"\s+#.*$", "", line).strip()
            if command:
                commands.append(command)
    return commands


def _replace_once(text: str, old: str, new: str, where: str) -> str:
    assert text.count(old) == 1, f"{where}: expected {old!r} exactly once"
    return text.replace(old, new)


class Watch:
    """Drains a child's pipe on a thread and lets the test wait for a line (bounded)."""

    def __init__(self, pipe: IO[str]) -> None:
        self.lines: list[str] = []
        self._closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(pipe,), daemon=True)
        self._thread.start()

    def _read(self, pipe: IO[str]) -> None:
        for line in pipe:
            with self._cond:
                self.lines.append(line)
                self._cond.notify_all()
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def wait_for(self, pattern: str, timeout_s: float) -> re.Match[str] | None:
        """The first line matching ``pattern``; None at EOF (the child exited) or timeout."""
        regex = re.compile(pattern)
        seen = 0

        def found() -> re.Match[str] | None:
            nonlocal seen
            for line in self.lines[seen:]:
                seen += 1
                if m := regex.search(line):
                    return m
            return None

        with self._cond:
            match: list[re.Match[str] | None] = [None]

            def ready() -> bool:
                match[0] = found()
                return match[0] is not None or self._closed

            self._cond.wait_for(ready, timeout_s)
            return match[0]

    def text(self) -> str:
        self._thread.join(STEP_TIMEOUT_S)
        return "".join(self.lines)


@contextmanager
def background(command: str, cwd: Path, env: dict[str, str]) -> Iterator[
        tuple[subprocess.Popen[str], Watch, Watch]]:  # fmt: skip
    """``command &``: bash execs it (so signals reach it); always terminated at exit."""
    proc = subprocess.Popen(["bash", "-c", f"exec {command}"], cwd=cwd, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    assert proc.stdout is not None and proc.stderr is not None
    out, err = Watch(proc.stdout), Watch(proc.stderr)
    try:
        yield proc, out, err
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(STEP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(STEP_TIMEOUT_S)


def foreground(command: str, cwd: Path, env: dict[str, str]) -> str:
    done = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, text=True,
                          capture_output=True, timeout=STEP_TIMEOUT_S)  # fmt: skip
    assert done.returncode == 0, f"{command}\n{done.stdout}\n{done.stderr}"
    return done.stdout


def test_tour_commands_are_the_ones_this_test_adapts() -> None:
    commands = tour_commands()
    joined = "\n".join(commands)
    for old in SMALLER:
        _replace_once(joined, old, SMALLER[old], "README tour")
    _replace_once(joined, ZENOH_README, "", "README tour")
    _replace_once(joined, SIM_PORT_README, "", "README tour")
    assert sum(c.endswith("&") for c in commands) == 2 and commands[-1] == "kill %1 %2"
    config = EXAMPLE_CONFIG.read_text(encoding="utf-8")
    _replace_once(config, SOCKETCAND_CONFIG, "", str(EXAMPLE_CONFIG))
    _replace_once(config, ZENOH_CONFIG, "", str(EXAMPLE_CONFIG))
    assert 'calibration = "../cal.json"' in config  # the fit's --out cal.json, from the root


@pytest.mark.slow
def test_readme_tour_runs(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1",
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    (tmp_path / "examples").mkdir()
    commands = tour_commands()
    for old, new in SMALLER.items():
        commands = [c.replace(old, new) for c in commands]
    offline = commands[: commands.index(next(c for c in commands if c.endswith("&")))]
    for command in offline:
        out = foreground(command, tmp_path, env)
    assert "valid-60min" in out  # evaluate scored the validation run with cal.json
    assert (tmp_path / "cal.json").is_file()
    streaming = commands[len(offline):]
    sim_cmd, run_cmd = (c.removesuffix("&").strip() for c in streaming[:2])
    listen_cmd, kill_cmd = streaming[2:]
    assert kill_cmd == "kill %1 %2" and run_cmd.startswith("gyrotherm run ")

    def attempt(zenoh_port: int) -> tuple[str, str, str]:
        """sim &, run &, listen: started back to back; stdout of each, daemon stderr."""
        sim_port = free_port()
        config = EXAMPLE_CONFIG.read_text(encoding="utf-8")
        config = _replace_once(config, SOCKETCAND_CONFIG, f"port = {sim_port}", "config")
        config = _replace_once(config, ZENOH_CONFIG,
                               f'listen = ["tcp/127.0.0.1:{zenoh_port}"]', "config")
        (tmp_path / "examples" / EXAMPLE_CONFIG.name).write_text(config, encoding="utf-8")
        with ExitStack() as stack:
            sim, _sim_out, sim_err = stack.enter_context(background(
                sim_cmd.replace(SIM_PORT_README, f"--port {sim_port}"), tmp_path, env))
            daemon, daemon_out, daemon_err = stack.enter_context(
                background(run_cmd, tmp_path, env))
            listen = subprocess.run(
                ["bash", "-c", listen_cmd.replace(ZENOH_README, f"tcp/127.0.0.1:{zenoh_port}")],
                cwd=tmp_path, env=env, text=True, capture_output=True, timeout=STEP_TIMEOUT_S)
            # kill %1 %2
            for proc in (sim, daemon):
                proc.send_signal(signal.SIGTERM)
            daemon.wait(STEP_TIMEOUT_S)
            sim.wait(STEP_TIMEOUT_S)
            err = daemon_err.text()
            if daemon.returncode != 0 or sim.returncode != 0:
                raise RuntimeError(f"gyrotherm run exited {daemon.returncode}, sim "
                                   f"{sim.returncode}:\n{err}\n{sim_err.text()}")
            assert listen.returncode == 0, f"{listen.stdout}\n{listen.stderr}\n{err}"
            return listen.stdout, daemon_out.text(), err

    listen, daemon_out, daemon_err = retry_on_address_in_use(attempt)
    received = re.search(r"rate: received=(\d+) gaps=0", listen)
    assert received and int(received[1]) >= 20, listen
    live = [line for line in listen.splitlines() if line.startswith("#")]
    assert live and not any("NO_CALIBRATION" in line for line in live), listen
    summary = re.search(r"frames in (\d+), published (\d+)", daemon_out)
    assert summary and int(summary[2]) >= 20, daemon_err
