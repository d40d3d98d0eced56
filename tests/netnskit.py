"""Test kit for multi-host tests: hosts made of Linux network namespaces and veth pairs.

:class:`Network` creates one network namespace per host (``ip netns add
gt-<pid>-<random>-<host>``, loopback up), joins hosts with veth pairs created
directly inside the two namespaces (no interface ever exists in the caller's
namespace) and addressed from a test-only private /30, and starts programs
inside a host with ``ip netns exec`` (which execs the program: the Popen pid is
the program's pid). Leaving the ``with`` block ends every process it started
(SIGTERM, then SIGKILL after a grace period), then whatever is still running
inside its namespaces (only their descendants can be), then deletes the
namespaces — also when the test failed. :func:`netns_unavailable` says why
namespaces cannot be made here (not root, no CAP_SYS_ADMIN, no ``ip``), so
tests skip instead of failing.

:class:`Process` collects a program's stdout and stderr lines from reader
threads; tests wait for a line or a JSON event with a deadline (never by
sleeping) and get every process's output tail in the failure message.

Run as a program (``python -m netnskit ...``, with tests/ on PYTHONPATH) it
provides the two remote ends of the multi-host test:

* ``router CONFIG``: a Zenoh router (eclipse-zenoh, the engine of zenohd) from a
  JSON5 file; prints ``{"event": "ready", "zid": ...}``, closes on SIGTERM.
* ``ground --vehicle V --sensor S --zenoh-config FILE``: a ground station, a
  :class:`gyrotherm.client.Subscriber` on a client session, printing one JSON
  line per event: ``transport`` (a router or peer came or went), ``health``
  (each health message, with the subscriber's per-stream sequence accounting,
  the gaps seen and checks of the corrected rates), ``calibration`` (reply to a
  ``query`` line on stdin) and ``final`` (after ``quit`` on stdin, or EOF).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

TESTS_DIR = Path(__file__).resolve().parent
NAME_PREFIX = "gt-"
STOP_GRACE_S = 5.0
_TAIL_LINES = 25

JsonEvent = dict[str, Any]


# ----------------------------------------------------------------- namespaces


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and result.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)} failed ({result.returncode}): "
                           f"{result.stderr.strip()}")
    return result


def netns_unavailable() -> str | None:
    """Why this process cannot create network namespaces, or None when it can."""
    if not sys.platform.startswith("linux"):
        return f"network namespaces need Linux (this is {sys.platform})"
    if shutil.which("ip") is None:
        return "the iproute2 'ip' command is not installed"
    if os.geteuid() != 0:
        return "creating network namespaces needs root (CAP_SYS_ADMIN); running as uid " \
               f"{os.geteuid()}"
    probe = f"{NAME_PREFIX}{os.getpid()}-probe-{uuid.uuid4().hex[:6]}"
    added = _ip("netns", "add", probe, check=False)
    if added.returncode != 0:
        return f"'ip netns add' failed: {added.stderr.strip() or added.returncode}"
    try:
        up = _ip("-n", probe, "link", "set", "lo", "up", check=False)
        if up.returncode != 0:
            return f"cannot configure a network namespace: {up.stderr.strip()}"
        veth = _ip("-n", probe, "link", "add", "p0", "type", "veth", "peer", "name", "p1",
                   check=False)
        if veth.returncode != 0:
            return f"cannot create veth pairs: {veth.stderr.strip()}"
    finally:
        _ip("netns", "del", probe, check=False)
    return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_namespaces() -> list[str]:
    """Delete ``gt-<pid>-…`` namespaces left by a test process that no longer exists."""
    listed = _ip("netns", "list", check=False).stdout.split("\n")
    removed = []
    for line in listed:
        name = line.split(" ", 1)[0]
        m = re.fullmatch(rf"{NAME_PREFIX}(\d+)-.+", name)
        if m and not _pid_alive(int(m.group(1))):
            if _ip("netns", "del", name, check=False).returncode == 0:
                removed.append(name)
    return removed


# ----------------------------------------------------------------- processes


class Process:
    """A program started in a host; its output lines are collected as they come."""

    def __init__(self, name: str, argv: Sequence[str], popen: subprocess.Popen[str]) -> None:
        self.name = name
        self.argv = list(argv)
        self.popen = popen
        self.out: list[str] = []
        self.err: list[str] = []
        self._cond = threading.Condition()
        self._open_streams = 2
        for stream, lines in ((popen.stdout, self.out), (popen.stderr, self.err)):
            threading.Thread(target=self._pump, args=(stream, lines), daemon=True,
                             name=f"{name}-pump").start()

    @property
    def pid(self) -> int:
        return self.popen.pid

    def _pump(self, stream: IO[str] | None, lines: list[str]) -> None:
        if stream is not None:
            with stream:
                for line in stream:
                    with self._cond:
                        lines.append(line.rstrip("\n"))
                        self._cond.notify_all()
        with self._cond:
            self._open_streams -= 1
            self._cond.notify_all()

    def running(self) -> bool:
        return self.popen.poll() is None

    def wait_line(self, pattern: str, *, timeout_s: float, stream: str = "out",
                  start: int = 0) -> re.Match[str]:
        """The first line (from index ``start``) of ``stream`` ("out", "err" or "any")
        matching ``pattern``; AssertionError after ``timeout_s`` or when output ends."""
        rx = re.compile(pattern)
        streams = {"out": [self.out], "err": [self.err], "any": [self.out, self.err]}[stream]
        deadline = time.monotonic() + timeout_s
        scanned = [start if lines is self.out or stream == "err" else 0 for lines in streams]
        with self._cond:
            while True:
                for k, lines in enumerate(streams):
                    for j in range(scanned[k], len(lines)):
                        m = rx.search(lines[j])
                        if m:
                            return m
                    scanned[k] = len(lines)
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._open_streams == 0:
                    break
                self._cond.wait(remaining)
        why = "timed out" if self._open_streams else f"ended (exit {self.popen.poll()})"
        raise AssertionError(f"{self.name}: no {stream} line matching {pattern!r} "
                             f"({why} after {timeout_s:g} s)\n{self.tail()}")

    def wait_event(self, predicate: Callable[[JsonEvent], bool], *, timeout_s: float,
                   start: int = 0, what: str = "event") -> tuple[int, JsonEvent]:
        """The first JSON object printed on stdout (from line ``start``) satisfying
        ``predicate``, and its line index; AssertionError after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        scanned = start
        while True:
            with self._cond:
                lines = self.out[scanned:]
            for k, line in enumerate(lines, start=scanned):
                if line.startswith("{"):
                    try:
                        event = json.loads(line)
                    except json.JSONDecodeError:
                        continue
                    if isinstance(event, dict) and predicate(event):
                        return k, event
            scanned += len(lines)
            with self._cond:
                remaining = deadline - time.monotonic()
                if len(self.out) == scanned and (remaining <= 0 or self._open_streams == 0):
                    break
                if len(self.out) == scanned:
                    self._cond.wait(remaining)
        why = "timed out" if self._open_streams else f"ended (exit {self.popen.poll()})"
        raise AssertionError(f"{self.name}: no {what} ({why} after {timeout_s:g} s)\n"
                             f"{self.tail()}")

    def send_line(self, text: str) -> None:
        if self.popen.stdin is not None:
            self.popen.stdin.write(text + "\n")
            self.popen.stdin.flush()

    def stop(self, *, sig: int = signal.SIGTERM, grace_s: float = STOP_GRACE_S) -> int:
        """Send ``sig``; SIGKILL after ``grace_s``; return the exit status."""
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.popen.send_signal(sig)
            try:
                self.popen.wait(grace_s)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(grace_s)
        if self.popen.stdin is not None:
            with contextlib.suppress(OSError):
                self.popen.stdin.close()
        return int(self.popen.returncode)

    def tail(self, n: int = _TAIL_LINES) -> str:
        with self._cond:
            out, err = self.out[-n:], self.err[-n:]
        return (f"--- {self.name} (pid {self.pid}, exit {self.popen.poll()}) stdout:\n"
                + "\n".join(out) + f"\n--- {self.name} stderr:\n" + "\n".join(err))


# ----------------------------------------------------------------- the network


@dataclass(frozen=True)
class Host:
    """One namespace: ``name`` as the test calls it, ``netns`` as ip(8) does."""

    name: str
    netns: str


class Network:
    """Hosts as network namespaces joined by veth pairs; a context manager."""

    def __init__(self, *, env: dict[str, str] | None = None) -> None:
        self.tag = f"{NAME_PREFIX}{os.getpid()}-{uuid.uuid4().hex[:6]}"
        self.hosts: dict[str, Host] = {}
        self.processes: list[Process] = []
        self._links = 0
        self.env = dict(os.environ if env is None else env)
        paths = [str(TESTS_DIR), *filter(None, self.env.get("PYTHONPATH", "").split(os.pathsep))]
        self.env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
        self.env["PYTHONUNBUFFERED"] = "1"

    def __enter__(self) -> Network:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def host(self, name: str) -> Host:
        """Create host ``name``: a fresh namespace with only ``lo``, brought up."""
        host = Host(name, f"{self.tag}-{name}")
        _ip("netns", "add", host.netns)
        self.hosts[name] = host
        _ip("-n", host.netns, "link", "set", "lo", "up")
        return host

    def link(self, a: Host, a_addr: str, b: Host, b_addr: str, *, prefix_len: int = 30) -> None:
        """A veth pair between ``a`` and ``b`` with these IPv4 addresses on one subnet."""
        self._links += 1
        ea, eb = f"l{self._links}{a.name[:6]}", f"l{self._links}{b.name[:6]}"
        _ip("-n", a.netns, "link", "add", ea, "type", "veth", "peer", "name", eb,
            "netns", b.netns)
        for host, dev, addr in ((a, ea, a_addr), (b, eb, b_addr)):
            _ip("-n", host.netns, "addr", "add", f"{addr}/{prefix_len}", "dev", dev)
            _ip("-n", host.netns, "link", "set", dev, "up")

    def spawn(self, host: Host, argv: Sequence[str], *, name: str | None = None,
              env: dict[str, str] | None = None, stdin: bool = False) -> Process:
        """Start ``argv`` inside ``host``; stdout/stderr are collected line by line."""
        full_env = {**self.env, **(env or {})}
        popen = subprocess.Popen(
            ["ip", "netns", "exec", host.netns, *argv], env=full_env, text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            stdin=subprocess.PIPE if stdin else subprocess.DEVNULL, bufsize=1)
        proc = Process(name or f"{host.name}:{Path(argv[0]).name}", argv, popen)
        self.processes.append(proc)
        return proc

    def tails(self) -> str:
        """Every process's last output lines (for failure messages)."""
        return "\n".join(p.tail() for p in self.processes)

    def close(self) -> None:
        """End every process started here, then anything left in the namespaces; delete them."""
        for proc in reversed(self.processes):
            proc.stop()
        for host in self.hosts.values():
            left = _ip("netns", "pids", host.netns, check=False).stdout.split()
            for pid in left:  # descendants of processes started here, if any
                with contextlib.suppress(ProcessLookupError, ValueError):
                    os.kill(int(pid), signal.SIGKILL)
        for host in self.hosts.values():
            _ip("netns", "del", host.netns, check=False)
        self.hosts.clear()


# ----------------------------------------------------------------- remote programs


def _emit(lock: threading.Lock, event: JsonEvent) -> None:
    line = json.dumps(event, default=str)
    with lock:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


def _router_main(args: argparse.Namespace) -> int:
    import zenoh

    # Blocked before zenoh starts its threads, so only sigwait() receives them.
    signals = {signal.SIGTERM, signal.SIGINT}
    signal.pthread_sigmask(signal.SIG_BLOCK, signals)
    session = zenoh.open(zenoh.Config.from_file(args.config))
    _emit(threading.Lock(), {"event": "ready", "zid": str(session.info.zid())})
    signal.sigwait(signals)
    session.close()
    return 0


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


class _Ground:
    """Subscriber callbacks: rate checks, gap list, one JSON line per health message."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.rates = 0
        self.bias_nonzero = 0
        self.calibrated = 0
        self.max_residual_dps = 0.0
        self.last_rate_seq: int | None = None
        self.rate_gaps: list[tuple[int, int]] = []
        self.last_rate: JsonEvent | None = None
        self.last_state: JsonEvent | None = None
        self.sub: Any = None

    def on_rate(self, msg: Any) -> None:
        from gyrotherm.codecs._wire import StatusFlags

        self.rates += 1
        residual = max(abs(r - c - b) for r, c, b in
                       zip(msg.raw_rate_dps, msg.rate_dps, msg.bias_dps, strict=True))
        self.max_residual_dps = max(self.max_residual_dps, residual)
        if any(b != 0.0 for b in msg.bias_dps):
            self.bias_nonzero += 1
        if not msg.flags & StatusFlags.NO_CALIBRATION:
            self.calibrated += 1
        last = self.last_rate_seq
        if last is not None and msg.seq != last + 1:
            self.rate_gaps.append((last, msg.seq))
        self.last_rate_seq = msg.seq
        self.last_rate = {"seq": msg.seq, "raw_rate_dps": list(msg.raw_rate_dps),
                          "rate_dps": list(msg.rate_dps), "bias_dps": list(msg.bias_dps),
                          "flags": int(msg.flags)}

    def on_state(self, msg: Any) -> None:
        self.last_state = {"seq": msg.seq, "temperature_c": _finite(msg.temperature_c),
                           "delta_t_c": _finite(msg.delta_t_c),
                           "bias_dps": list(msg.bias_dps), "flags": int(msg.flags)}

    def snapshot(self) -> JsonEvent:
        stats = self.sub.stats() if self.sub is not None else None
        streams = {}
        if stats is not None:
            for name in ("rate", "state", "health"):
                s = getattr(stats, name)
                streams[name] = {"received": s.received, "gaps": s.gaps, "missing": s.missing,
                                 "resets": s.resets, "duplicates": s.duplicates,
                                 "undecodable": s.undecodable, "last_seq": s.last_seq}
        return {"streams": streams,
                "checks": {"rates": self.rates, "bias_nonzero": self.bias_nonzero,
                           "calibrated": self.calibrated,
                           "max_residual_dps": self.max_residual_dps},
                "rate_gaps": self.rate_gaps[:20], "last_rate": self.last_rate,
                "last_state": self.last_state}

    def on_health(self, msg: Any) -> None:
        _emit(self.lock, {"event": "health", **_health_dict(msg), **self.snapshot()})


def _health_dict(msg: Any) -> JsonEvent:
    return {"health": {"seq": msg.seq, "uptime_s": msg.uptime_s,
                       "frames_received": msg.frames_received,
                       "frames_published": msg.frames_published, "drops": dict(msg.drops),
                       "flags": int(msg.flags), "calibration_id": msg.calibration_id}}


def _ground_main(args: argparse.Namespace) -> int:
    import zenoh

    from gyrotherm._zenoh import open_session
    from gyrotherm.client import Subscriber

    ground = _Ground()
    session = open_session(config_file=args.zenoh_config)

    def on_transport(event: Any) -> None:
        kind = "open" if event.kind == zenoh.SampleKind.PUT else "close"
        _emit(ground.lock, {"event": "transport", "kind": kind,
                            "whatami": str(event.transport.whatami).lower(),
                            "zid": str(event.transport.zid)})

    listener = session.info.declare_transport_events_listener(on_transport, history=True)
    sub = Subscriber(args.vehicle, args.sensor, session=session, on_rate=ground.on_rate,
                     on_state=ground.on_state, on_health=ground.on_health)
    ground.sub = sub
    _emit(ground.lock, {"event": "subscribed", "key": sub.keys.rate.rsplit("/", 1)[0]})
    try:
        for line in sys.stdin:
            command = line.strip()
            if command == "query":
                try:
                    info = sub.query_calibration(timeout_s=5.0)
                except Exception as exc:  # reported, the test decides
                    _emit(ground.lock, {"event": "calibration", "error": repr(exc)})
                else:
                    health = _health_dict(info.health) if info.health else {"health": None}
                    _emit(ground.lock, {"event": "calibration",
                                        "calibration_id": info.calibration_id,
                                        "model": (info.calibration or {}).get("model"),
                                        **health})
            elif command == "quit":
                break
    finally:
        sub.close()
        listener.undeclare()
        _emit(ground.lock, {"event": "final", **ground.snapshot()})
        session.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m netnskit")
    sub = parser.add_subparsers(dest="program", required=True)
    router = sub.add_parser("router", help="a zenoh router from a JSON5 config")
    router.add_argument("config")
    router.set_defaults(func=_router_main)
    ground = sub.add_parser("ground", help="a Subscriber printing JSON events")
    ground.add_argument("--vehicle", required=True)
    ground.add_argument("--sensor", required=True)
    ground.add_argument("--zenoh-config", required=True)
    ground.set_defaults(func=_ground_main)
    args = parser.parse_args(argv)
    code: int = args.func(args)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
