"""The Rust client (clients/rust): its own tests (shared wire vectors, gaps, latency) and,
end to end, its servo-loop example against a running daemon, compared message by
message with what the Python ``Subscriber`` received on the same stream.

Skips with a reason when cargo is absent; with cargo, a build error fails. Builds
offline first (the crates cached in ~/.cargo), then online.
"""

from __future__ import annotations

import json
import os
import queue
import re
import shlex
import shutil
import subprocess
import threading
from pathlib import Path
from typing import Any

import pytest

from gyrotherm._zenoh import keys, session_config
from gyrotherm.bus import open_bus
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, RateMessage, Run
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
    encode_rate,
)
from streamkit import open_ephemeral, run_frames

ROOT = Path(__file__).resolve().parents[2]
CRATE = ROOT / "clients" / "rust"
README = ROOT / "README.md"
TIMEOUT_S = 20.0
BUILD_TIMEOUT_S = 3600.0  # a first build of zenoh on 2 cores takes minutes


def _cargo() -> str:
    found = shutil.which("cargo") or shutil.which(str(Path.home() / ".cargo" / "bin" / "cargo"))
    if found is None:
        pytest.skip("cargo not found (PATH, ~/.cargo/bin): Rust client not built or tested")
    return found


def _cargo_run(args: list[str]) -> subprocess.CompletedProcess[str]:
    """``cargo ARGS --offline``, then online if the offline attempt could not resolve."""
    cargo = _cargo()
    env = {**os.environ, "CARGO_TERM_COLOR": "never"}
    out = subprocess.run([cargo, *args, "--offline"], cwd=CRATE, env=env, text=True,
                         capture_output=True, timeout=BUILD_TIMEOUT_S)  # fmt: skip
    if out.returncode != 0 and "offline" in out.stderr:
        out = subprocess.run([cargo, *args], cwd=CRATE, env=env, text=True,
                             capture_output=True, timeout=BUILD_TIMEOUT_S)  # fmt: skip
    return out


@pytest.fixture(scope="module")
def built() -> None:
    out = _cargo_run(["build", "--examples"])
    assert out.returncode == 0, f"cargo build --examples failed:\n{out.stderr[-4000:]}"


def test_rust_crate_tests_pass(built: None) -> None:
    """``cargo test``: decoding of every vector of tests/vectors/wire-v1.json, field by
    field; gap and latency accounting on hand-computed sequences; error texts."""
    out = _cargo_run(["test"])
    assert out.returncode == 0, f"cargo test failed:\n{out.stdout[-4000:]}\n{out.stderr[-4000:]}"
    passed = [int(n) for n in re.findall(r"test result: ok\. (\d+) passed", out.stdout)]
    assert sum(passed) >= 15, out.stdout
    assert "every_vector_decodes_to_its_fields ... ok" in out.stdout


def _readme_command() -> list[str]:
    text = README.read_text(encoding="utf-8")
    start = text.index("## Consuming the rates outside Python")
    section = text[start:text.index("\n## ", start + 1)]
    blocks = [b for b in re.findall(r"```sh\n(.*?)```", section, re.S) if "cargo run" in b]
    assert len(blocks) == 1, "README: one sh block with the Rust client's cargo command"
    line = blocks[0].replace("\\\n", " ").split("#")[0]
    argv = shlex.split(line)
    assert argv[:3] == ["cd", "clients/rust", "&&"], argv
    return argv[3:]


def _set(argv: list[str], flag: str, value: str) -> list[str]:
    i = argv.index(flag)
    return [*argv[: i + 1], value, *argv[i + 2 :]]


def _reader(stream: Any, lines: queue.Queue[str | None]) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


def _no_constant(name: str) -> Any:
    raise AssertionError(f"not JSON (RFC 8259): {name}")


def strict_json(line: str) -> dict[str, Any]:
    """One line of the example's output, parsed as RFC 8259 JSON: Python's ``json``
    would take ``NaN`` and ``Infinity``; here they fail."""
    value = json.loads(line, parse_constant=_no_constant)
    assert isinstance(value, dict), line
    return value


def flag_names(flags: int) -> list[str]:
    """StatusFlags names of ``flags``, lowest bit first; unknown bits as hex."""
    known = {int(f): str(f.name) for f in StatusFlags if f}
    return [known.get(1 << i, hex(1 << i)) for i in range(64) if flags >> i & 1]


def check_events(got: list[dict[str, Any]], rates: list[RateMessage], gain: float) -> None:
    """Rust's events against the Python Subscriber's messages: a command only from a
    clean sample (flags 0), every flagged one skipped with its flag names."""
    assert [g["seq"] for g in got] == [m.seq for m in rates]
    for g, m in zip(got, rates, strict=True):
        assert g["flags"] == int(m.flags)
        if m.flags:
            assert g["event"] == "skipped" and "command_dps" not in g, g
            assert g["flag_names"] == flag_names(int(m.flags))
        else:
            assert g["event"] == "sample"
            assert g["command_dps"] == -gain * m.rate_dps[2]


def _next_json(lines: queue.Queue[str | None], proc: subprocess.Popen[str]) -> dict[str, Any]:
    while True:
        try:
            line = lines.get(timeout=TIMEOUT_S * 3)
        except queue.Empty:
            pytest.fail("the Rust example printed nothing within the timeout")
        if line is None:
            err = proc.stderr.read() if proc.stderr else ""
            pytest.fail(f"the Rust example ended early (exit {proc.wait()}): {err[-2000:]}")
        if line.startswith("{"):
            return strict_json(line)


def test_readme_rust_servo_loop_against_the_daemon(
    built: None, daemon: tuple[str, int], runs: list[Run]
) -> None:
    """The README's command (vehicle, endpoint and count adapted, ``--json`` added)
    decodes the same rate messages as the Python Subscriber: same seq, same values."""
    channel, port = daemon
    run = runs[1].slice(0, 200)
    frames = list(run_frames(run, FrameEncoder()))
    n = len(run)
    argv = _readme_command()
    assert argv[:4] == ["cargo", "run", "--example", "servo_loop"], argv
    assert _parser_values(argv) == {"--vehicle": "veh01", "--sensor": "imu0",
                                    "--connect": "tcp/127.0.0.1:7447", "--max-samples": "1000"}
    argv = _set(argv, "--vehicle", "testcar")
    argv = _set(argv, "--connect", f"tcp/127.0.0.1:{port}")
    argv = _set(argv, "--max-samples", str(n))
    argv = [_cargo(), *argv[1:2], "--offline", *argv[2:], "--json", "--timeout-s", str(TIMEOUT_S)]
    rates: list[RateMessage] = []
    with Subscriber("testcar", "imu0", connect=[f"tcp/127.0.0.1:{port}"],
                    on_rate=rates.append) as sub, \
            open_bus(interface="virtual", channel=channel) as bus:  # fmt: skip
        proc = subprocess.Popen(argv, cwd=CRATE, text=True, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)  # fmt: skip
        try:
            lines: queue.Queue[str | None] = queue.Queue()
            threading.Thread(target=_reader, args=(proc.stdout, lines), daemon=True).start()
            ready = _next_json(lines, proc)  # Rust got a health message, queried the calibration
            assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
            calibration_id = sub.query_calibration(timeout_s=TIMEOUT_S).calibration_id
            for msg in frames:
                bus.send(msg)
            got = [_next_json(lines, proc) for _ in range(n)]
            done = _next_json(lines, proc)
            assert proc.wait(TIMEOUT_S) == 0
            assert sub.wait_for(lambda s: s.rate.received >= n, timeout_s=TIMEOUT_S)
            py_stats = sub.stats().rate
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert ready == {"event": "ready", "calibration_id": calibration_id}
    assert calibration_id  # the daemon fixture loads one
    check_events(got, rates, gain=2.0)
    assert [g["seq"] for g in got] == list(range(got[0]["seq"], got[0]["seq"] + n))
    for g, m in zip(got, rates, strict=True):
        # both decode the same float 64; Rust prints its shortest round-trip form
        assert g["rate_dps"] == list(m.rate_dps)
        assert g["raw_rate_dps"] == list(m.raw_rate_dps)
        assert g["bias_dps"] == list(m.bias_dps)
        assert (g["sensor_time_s"], g["receive_time_s"]) == (m.sensor_time_s, m.receive_time_s)
    assert any(g["rate_dps"] != g["raw_rate_dps"] for g in got)  # compensated: bias removed
    clean = sum(not m.flags for m in rates)
    assert clean > 0, "the daemon flagged every sample: no command was checked"
    stats = done["rate"]
    assert done["event"] == "done" and done["samples"] == n
    assert (done["commands"], done["skipped"]) == (clean, n - clean)
    counts = (stats["received"], stats["gaps"], stats["missing"], stats["undecodable"])
    assert counts == (n, 0, 0, 0)
    assert (py_stats.received, py_stats.gaps, py_stats.undecodable) == (n, 0, 0)
    assert stats["latency_count"] == n
    assert 0 <= stats["latency_p50_ms"] <= stats["latency_p99_ms"] <= stats["latency_max_ms"]
    assert stats["latency_max_ms"] < TIMEOUT_S * 1e3
    print(f"rust: {n} samples, gaps 0, latency p50 {stats['latency_p50_ms']:.2f} ms, "
          f"p99 {stats['latency_p99_ms']:.2f} ms; python: p50 "
          f"{py_stats.latency.p50_s * 1e3:.2f} ms, p99 {py_stats.latency.p99_s * 1e3:.2f} ms")


def test_rust_and_python_account_gaps_alike(built: None) -> None:
    """Hand-made stream with a gap, a duplicate, an undecodable payload, a publisher
    restart and a NaN rate: the Rust example and the Python Subscriber count the same."""
    session, endpoint = open_ephemeral(session_config(listen=["tcp/127.0.0.1:0"]))
    k = keys("gapcar", "imu0")
    cal = encode_calibration_info(CalibrationInfo("cal-gaps", None, None))
    queryable = session.declare_queryable(k.calibration, lambda q: q.reply(k.calibration, cal))
    # 0 1 2 [3 4] 5 5(dup) 6 <garbage> 3(restart: 0..2 missing) 4 [5..9] 10 11(NaN)
    seqs = [0, 1, 2, 5, 5, 6, None, 3, 4, 10, 11]
    nan = float("nan")
    # flagged samples (no command from them): stale T at 1, invalid bias with clamped T
    # at 6, a bit this version does not know (a newer daemon's) at 10
    sent_flags = {1: StatusFlags.TEMPERATURE_STALE,
                  6: StatusFlags.BIAS_INVALID | StatusFlags.T_CLAMPED, 10: StatusFlags(0x8000)}
    payloads = [b"\x93garbage" if q is None else encode_rate(RateMessage(
        q, 0.01 * q, 1.7e9 + q, (nan if q == 11 else 0.5 * q, -0.25, 1.0 + q),
        (0.5 * q, 0.0, 1.0), (0.0, 0.25, -float(q)),
        sent_flags.get(q, StatusFlags.NONE))) for q in seqs]  # fmt: skip
    n = sum(q is not None for q in seqs)
    cargo = _cargo()
    argv = [cargo, "run", "--offline", "--example", "servo_loop", "--", "--vehicle", "gapcar",
            "--sensor", "imu0", "--connect", endpoint, "--max-samples", str(n), "--json",
            "--timeout-s", str(TIMEOUT_S)]  # fmt: skip
    rates: list[RateMessage] = []
    with Subscriber("gapcar", "imu0", session=session, on_rate=rates.append) as sub:
        proc = subprocess.Popen(argv, cwd=CRATE, text=True, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)  # fmt: skip
        try:
            lines: queue.Queue[str | None] = queue.Queue()
            threading.Thread(target=_reader, args=(proc.stdout, lines), daemon=True).start()
            # health until the Rust subscriber reports one (its route exists): each wait
            # ends on the next line printed or after 0.2 s, at most TIMEOUT_S in all
            ready: dict[str, Any] | None = None
            for hseq in range(int(TIMEOUT_S / 0.2)):
                session.put(k.health, encode_health(HealthMessage(
                    hseq, None, 1.7e9, 1.0, 0, 0, {}, StatusFlags.NO_CALIBRATION)))  # fmt: skip
                try:
                    line = lines.get(timeout=0.2)
                except queue.Empty:
                    continue
                assert line is not None, proc.stderr.read() if proc.stderr else ""
                ready = strict_json(line)
                break
            assert ready == {"event": "ready", "calibration_id": "cal-gaps"}
            for payload in payloads:
                session.put(k.rate, payload)
            got = [_next_json(lines, proc) for _ in range(n)]
            done = _next_json(lines, proc)
            assert proc.wait(TIMEOUT_S) == 0
            assert sub.wait_for(lambda s: s.rate.received + s.rate.undecodable >= len(seqs),
                                timeout_s=TIMEOUT_S)  # fmt: skip
            py = sub.stats().rate
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            queryable.undeclare()
        session.close()
    assert [g["seq"] for g in got] == [q for q in seqs if q is not None]
    check_events(got, rates, gain=2.0)
    assert got[-1]["rate_dps"] == [None, -0.25, 12.0]  # NaN printed as null
    assert got[-1]["flags"] == int(StatusFlags.NON_FINITE)
    assert got[-1]["event"] == "skipped" and got[-1]["flag_names"] == ["NON_FINITE"]
    assert [g["seq"] for g in got if g["event"] == "skipped"] == [1, 6, 10, 11]
    assert done["skipped_by_flag"] == {"TEMPERATURE_STALE": 1, "T_CLAMPED": 1,
                                       "BIAS_INVALID": 1, "0x8000": 1, "NON_FINITE": 1}
    assert (done["samples"], done["commands"], done["skipped"]) == (n, n - 4, 4)
    rust = done["rate"]
    expected = {"received": n, "gaps": 3, "missing": 2 + 3 + 5, "resets": 1, "duplicates": 1,
                "undecodable": 1, "non_finite": 1}  # fmt: skip
    assert {key: rust[key] for key in expected} == expected
    assert {key: getattr(py, key) for key in expected} == expected
    assert rust["latency_count"] == py.latency.count == n


def _parser_values(argv: list[str]) -> dict[str, str]:
    """The example's ``--flag value`` pairs after ``--`` (what the README sets)."""
    rest = argv[argv.index("--") + 1 :]
    return {rest[i]: rest[i + 1] for i in range(0, len(rest), 2)}
