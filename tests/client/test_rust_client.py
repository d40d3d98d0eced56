"""The Rust client (clients/rust): its own tests (shared wire vectors, gaps, latency) and,
end to end, its servo-loop example against a running daemon, compared message by
message with what the Python ``Subscriber`` received on the same stream: a command only
from a clean sample (flags 0), every flagged one skipped and counted, each output line
RFC 8259 JSON (no NaN). Through the secured deployments of docs/operations.md (routers
from deploy/zenoh as zenohd and as eclipse-zenoh: mutual TLS with acl-router.json5, a
login with router.json5), the example with ``--zenoh-config`` gets the daemon's messages,
and fails (exit 2, the reason on stderr) without a client certificate, with another CA's
certificate or with a wrong password.

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
import uuid
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from gyrotherm._zenoh import PLACEHOLDER_PASSWORD, keys, open_session, session_config
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
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, parse_config
from pkikit import make_pki
from streamkit import free_port, open_ephemeral, run_frames

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


def _declared_rust_version() -> str:
    found = re.findall(r'^rust-version = "([0-9.]+)"$', (CRATE / "Cargo.toml").read_text(), re.M)
    assert len(found) == 1, "Cargo.toml: one rust-version"
    return str(found[0])


def test_rust_crate_builds_with_its_declared_minimum_rust_version() -> None:
    """``rust-version`` in Cargo.toml is checked, not just declared: that toolchain builds
    every target (lib, example, tests) with the locked dependencies. Skips, naming the
    install command, when the toolchain is not installed (the test sets
    RUSTUP_AUTO_INSTALL=0: rustup never downloads it by itself)."""
    cargo = _cargo()
    msrv = _declared_rust_version()
    version = f"{msrv}.0" if msrv.count(".") == 1 else msrv
    rustup = shutil.which("rustup") or shutil.which(str(Path.home() / ".cargo" / "bin" / "rustup"))
    installed = subprocess.run([rustup, "toolchain", "list"], text=True, capture_output=True,
                               timeout=60).stdout if rustup else ""  # fmt: skip
    if not re.search(rf"^{re.escape(version)}-", installed, re.M):
        pytest.skip(f"Rust {version} (Cargo.toml rust-version) is not installed: "
                    f"`rustup toolchain install {version} --profile minimal` to check it")
    assert rustup is not None
    target = CRATE / "target" / f"msrv-{version}"
    args = [f"+{version}", "build", "--locked", "--all-targets", "--target-dir", str(target)]
    env = {**os.environ, "CARGO_TERM_COLOR": "never", "RUSTUP_AUTO_INSTALL": "0"}
    out = subprocess.run([cargo, *args, "--offline"], cwd=CRATE, env=env, text=True,
                         capture_output=True, timeout=BUILD_TIMEOUT_S)  # fmt: skip
    if out.returncode != 0 and "offline" in out.stderr:
        out = subprocess.run([cargo, *args], cwd=CRATE, env=env, text=True,
                             capture_output=True, timeout=BUILD_TIMEOUT_S)  # fmt: skip
    assert out.returncode == 0, f"cargo +{version} build failed:\n{out.stderr[-4000:]}"
    assert "warning:" not in out.stderr, out.stderr[-4000:]
    rustc = subprocess.run([rustup, "run", version, "rustc", "--version"], text=True,
                           capture_output=True, timeout=60).stdout  # fmt: skip
    assert rustc.startswith(f"rustc {version} "), rustc


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
    print(f"rust: {n} samples ({done['commands']} commands, {done['skipped_by_flag']} skipped), "
          f"gaps 0, latency p50 {stats['latency_p50_ms']:.2f} ms, "
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


# --------------------------------------------------------- secured deployments
# docs/operations.md, "Zenoh configurations" and "Threat model": a router from
# deploy/zenoh (acl-router.json5: mutual TLS only, access by certificate CN;
# router.json5: usrpwd login, access by user name), run as zenohd and as eclipse-zenoh
# in router mode; the real daemon a client of it under its own identity; the Rust
# example with ``--zenoh-config`` a viewer's copy of the shipped client file, edited
# as a user would (addresses, files, login). The Python Subscriber opens the same file
# (``open_session(config_file=...)``) on the same router as the reference.

DEPLOY_ZENOH = ROOT / "deploy" / "zenoh"
PASSWORDS = {"gyrotherm-daemon": "daemon-secret-5e1d", "gyrotherm-viewer": "viewer-secret-c07a"}


def _edit(text: str, old: str, new: str, count: int = 1) -> str:
    assert text.count(old) == count, f"expected {old!r} {count}× in the shipped file"
    return text.replace(old, new)


def _tls_client_file(path: Path, pki: Path, name: str, endpoint: str, *,
                     certificate: bool = True, timeout_ms: int | None = None) -> Path:  # fmt: skip
    """tls-mutual.json5 as a client of the router at ``endpoint`` with the node's
    certificate (CN ``name``) or, ``certificate=False``, none (the CA only)."""
    text = (DEPLOY_ZENOH / "tls-mutual.json5").read_text(encoding="utf-8")
    text = _edit(text, 'mode: "peer"', 'mode: "client"')
    text = _edit(text, '"tls/127.0.0.1:7447",', "")  # a client does not listen
    text = _edit(text, '// "tls/192.168.50.1:7447",', json.dumps(endpoint) + ",")
    text = _edit(text, "/etc/gyrotherm/tls/ca.pem", str(pki / "test-ca.pem"))
    text = _edit(text, "/etc/gyrotherm/tls/gyrotherm-key.pem", str(pki / f"{name}-key.pem"), 2)
    text = _edit(text, "/etc/gyrotherm/tls/gyrotherm.pem", str(pki / f"{name}.pem"), 2)
    if not certificate:
        lines = text.splitlines(keepends=True)
        kept = [ln for ln in lines if not re.match(r"\s*connect_(certificate|private_key):", ln)]
        assert len(lines) - len(kept) == 2
        text = "".join(kept)
    if timeout_ms is not None:
        text = _edit(text, "connect: {", f"connect: {{\n    timeout_ms: {timeout_ms},")
    path.write_text(text, encoding="utf-8")
    return path


def _login_file(path: Path, endpoint: str, user: str, password: str,
                timeout_ms: int | None = None) -> Path:  # fmt: skip
    """client-of-router.json5 with the router's address and ``user``'s login."""
    text = (DEPLOY_ZENOH / "client-of-router.json5").read_text(encoding="utf-8")
    text = _edit(text, '"tcp/127.0.0.1:7447"', json.dumps(endpoint))
    text = _edit(text, 'user: "gyrotherm-daemon"', f"user: {json.dumps(user)}")
    text = _edit(text, PLACEHOLDER_PASSWORD, password)
    if timeout_ms is not None:
        text = _edit(text, "timeout_ms: 20000", f"timeout_ms: {timeout_ms}")
    path.write_text(text, encoding="utf-8")
    return path


def _router_text(name: str, endpoint: str, pki: Path, users: Path) -> str:
    text = (DEPLOY_ZENOH / name).read_text(encoding="utf-8")
    proto = endpoint.split("/", 1)[0]
    text = _edit(text, f'"{proto}/127.0.0.1:7447"', json.dumps(endpoint))
    if name == "acl-router.json5":
        text = _edit(text, "/etc/zenoh/tls/ca.pem", str(pki / "test-ca.pem"))
        text = _edit(text, "/etc/zenoh/tls/router-key.pem", str(pki / "gyrotherm-router-key.pem"))
        text = _edit(text, "/etc/zenoh/tls/router.pem", str(pki / "gyrotherm-router.pem"))
    else:
        text = _edit(text, "/etc/zenoh/gyrotherm-users.txt", str(users))
    return text


@contextmanager
def _router(kind: str, name: str, pki: Path, tmp: Path) -> Iterator[str]:
    """deploy/zenoh/``name`` running as ``kind``; yield the endpoint it listens on."""
    users = tmp / "gyrotherm-users.txt"
    users.write_text("".join(f"{u}:{p}\n" for u, p in PASSWORDS.items()), encoding="utf-8")
    proto = "tls" if name == "acl-router.json5" else "tcp"
    if kind == "eclipse-zenoh":
        config = zenoh.Config.from_json5(_router_text(name, f"{proto}/127.0.0.1:0", pki, users))
        session, endpoint = open_ephemeral(config)
        try:
            yield endpoint
        finally:
            session.close()
        return
    zenohd = shutil.which("zenohd") or shutil.which(str(Path.home() / ".cargo/bin/zenohd"))
    if zenohd is None:
        pytest.skip("zenohd not found (PATH, ~/.cargo/bin): the eclipse-zenoh variant runs "
                    "the same router engine")  # fmt: skip
    endpoint = f"{proto}/127.0.0.1:{free_port()}"
    path = tmp / f"zenohd-{name}"
    path.write_text(_router_text(name, endpoint, pki, users), encoding="utf-8")
    with (tmp / "zenohd.log").open("w") as log:
        proc = subprocess.Popen([zenohd, "-c", str(path)], stdout=log, stderr=subprocess.STDOUT,
                                env={"RUST_LOG": "info", "PATH": "/usr/bin:/bin"})  # fmt: skip
        try:
            yield endpoint
        finally:
            proc.terminate()
            try:
                proc.wait(TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(TIMEOUT_S)


@contextmanager
def _daemon_via(zenoh_file: Path, calibration: Calibration, tmp: Path) -> Iterator[str]:
    """The real daemon, its zenoh session from ``zenoh_file``; yield its CAN channel."""
    channel = f"sec-{uuid.uuid4().hex[:8]}"
    cfg = parse_config({
        "vehicle": "testcar", "sensor": "imu0",
        "calibration": str(calibration.save(tmp / "cal.json")), "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"config": str(zenoh_file)},
    }, base_dir=tmp)  # fmt: skip
    daemon = Daemon(cfg)
    failure: list[BaseException] = []

    def run() -> None:
        try:
            daemon.run()
        except BaseException as exc:  # reported below, not lost in the thread
            failure.append(exc)
            daemon.ready.set()

    thread = threading.Thread(target=run, name="daemon", daemon=True)
    thread.start()
    try:
        assert daemon.ready.wait(TIMEOUT_S * 2), "daemon not ready"
        assert not failure, f"daemon failed to start: {failure[0]!r}"
        yield channel
    finally:
        daemon.stop()
        thread.join(TIMEOUT_S)


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.kill()
    proc.wait()


def _servo_loop(*args: str) -> list[str]:
    return [_cargo(), "run", "--offline", "--quiet", "--example", "servo_loop", "--",
            "--vehicle", "testcar", "--sensor", "imu0", *args]  # fmt: skip


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("openssl") is None:
        pytest.skip("the openssl CLI is not installed: cannot make test certificates")
    return Path(make_pki(tmp_path_factory.mktemp("pki"),
                         ("gyrotherm-router", "gyrotherm-daemon", "gyrotherm-viewer"),
                         "gyrotherm-viewer-rogue"))  # fmt: skip


ROUTERS = ["acl-router.json5", "router.json5"]
KINDS = ["zenohd", "eclipse-zenoh"]


def _client_files(name: str, tmp: Path, pki: Path, endpoint: str) -> tuple[Path, Path]:
    """The daemon's and the viewer's client file for the router ``name``."""
    if name == "acl-router.json5":
        return (_tls_client_file(tmp / "daemon.json5", pki, "gyrotherm-daemon", endpoint,
                                 timeout_ms=int(TIMEOUT_S * 1000)),
                _tls_client_file(tmp / "viewer.json5", pki, "gyrotherm-viewer", endpoint))
    return (_login_file(tmp / "daemon.json5", endpoint, "gyrotherm-daemon",
                        PASSWORDS["gyrotherm-daemon"]),
            _login_file(tmp / "viewer.json5", endpoint, "gyrotherm-viewer",
                        PASSWORDS["gyrotherm-viewer"]))  # fmt: skip


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ROUTERS)
def test_rust_servo_loop_through_a_secured_router(
    built: None, pki: Path, tmp_path: Path, runs: list[Run], calibration: Calibration,
    name: str, kind: str,
) -> None:
    """The daemon (CN / user gyrotherm-daemon) publishes through the router; the Rust
    example, with the viewer's file, gets every rate message the Python Subscriber
    gets with the same file, and the daemon's calibration id through the router."""
    run = runs[1].slice(0, 100)
    frames = list(run_frames(run, FrameEncoder()))
    n = len(run)
    with ExitStack() as stack:
        endpoint = stack.enter_context(_router(kind, name, pki, tmp_path))
        daemon_file, viewer_file = _client_files(name, tmp_path, pki, endpoint)
        channel = stack.enter_context(_daemon_via(daemon_file, calibration, tmp_path))
        rates: list[RateMessage] = []
        session = open_session(config_file=viewer_file)  # the viewer's file, in Python
        stack.callback(session.close)
        sub = stack.enter_context(Subscriber("testcar", "imu0", session=session,
                                             on_rate=rates.append))  # fmt: skip
        assert sub.wait_for(lambda s: s.health.received >= 1, timeout_s=TIMEOUT_S)
        calibration_id = sub.query_calibration(timeout_s=TIMEOUT_S).calibration_id
        bus = stack.enter_context(open_bus(interface="virtual", channel=channel))
        proc = subprocess.Popen(
            _servo_loop("--zenoh-config", str(viewer_file), "--max-samples", str(n), "--json",
                        "--timeout-s", str(TIMEOUT_S)),
            cwd=CRATE, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        stack.callback(_stop, proc)
        lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=_reader, args=(proc.stdout, lines), daemon=True).start()
        ready = _next_json(lines, proc)  # Rust got a health message through the router
        for msg in frames:
            bus.send(msg)
        got = [_next_json(lines, proc) for _ in range(n)]
        done = _next_json(lines, proc)
        assert proc.wait(TIMEOUT_S) == 0
        assert sub.wait_for(lambda s: s.rate.received >= n, timeout_s=TIMEOUT_S)
    assert ready == {"event": "ready", "calibration_id": calibration_id}
    assert calibration_id
    check_events(got, rates, gain=2.0)
    assert [g["seq"] for g in got] == list(range(got[0]["seq"], got[0]["seq"] + n))
    assert done["samples"] == n and done["rate"]["gaps"] == 0
    assert done["commands"] == sum(not m.flags for m in rates) > 0
    print(f"{name} ({kind}): {n} samples, {done['commands']} commands, skipped "
          f"{done['skipped_by_flag']}, p99 {done['rate']['latency_p99_ms']:.2f} ms")


#: the example's stderr when zenoh cannot open the session of a config file (%s: the file)
_OPEN_FAILED = (r'servo_loop: cannot open zenoh session \(config file "%s"\): Unable to connect '
                r".+ \(unreachable, or the router/peer refused this session: .+\)\n")


def _ready_only(viewer_file: Path) -> subprocess.CompletedProcess[str]:
    """The example up to its ``ready`` line (the daemon's health and calibration reply
    arrived), then done (``--max-samples 0``)."""
    return subprocess.run(
        _servo_loop("--zenoh-config", str(viewer_file), "--max-samples", "0", "--json",
                    "--timeout-s", "5", "--ready-timeout-s", "5"),
        cwd=CRATE, text=True, capture_output=True, timeout=TIMEOUT_S * 3)  # fmt: skip


@pytest.mark.parametrize("kind", KINDS)
def test_rust_refused_without_a_client_certificate(
    built: None, pki: Path, tmp_path: Path, calibration: Calibration, kind: str
) -> None:
    """acl-router.json5 admits mutual TLS only: the viewer's file without its
    certificate (CA only), or with a certificate of another CA, cannot open a session:
    exit status 2 and the reason on stderr, no output. The daemon is up and a viewer
    with the right certificate gets through (control), so only the certificate differs."""
    with ExitStack() as stack:
        endpoint = stack.enter_context(_router(kind, "acl-router.json5", pki, tmp_path))
        daemon_file, viewer_file = _client_files("acl-router.json5", tmp_path, pki, endpoint)
        stack.enter_context(_daemon_via(daemon_file, calibration, tmp_path))
        control = _ready_only(viewer_file)
        assert control.returncode == 0 and strict_json(control.stdout.splitlines()[0])[
            "event"] == "ready", control.stderr  # fmt: skip
        for label, bad in {
            "no certificate": _tls_client_file(tmp_path / "nocert.json5", pki,
                                               "gyrotherm-viewer", endpoint, certificate=False),
            "another CA's certificate": _tls_client_file(
                tmp_path / "rogue.json5", pki, "gyrotherm-viewer-rogue", endpoint),
        }.items():  # fmt: skip
            out = _ready_only(bad)
            print(f"{label}: exit {out.returncode}: {out.stderr.strip()}")
            assert out.returncode == 2, (label, out.stdout, out.stderr)
            assert out.stdout == "", label
            assert re.fullmatch(rf"{_OPEN_FAILED % re.escape(str(bad))}", out.stderr), (
                label, out.stderr)  # fmt: skip
            assert ".rs:" not in out.stderr


@pytest.mark.parametrize("kind", KINDS)
def test_rust_refused_with_a_wrong_password(
    built: None, pki: Path, tmp_path: Path, calibration: Calibration, kind: str
) -> None:
    """router.json5 requires a login: the viewer's file with a wrong password, or the
    shipped placeholder, cannot open a session (exit status 2, the reason on stderr);
    the same file with the right password gets through (control). The wrong-password
    file waits ``connect/timeout_ms`` for the router to accept it (the shipped 20 s,
    2 s here) and then fails."""
    with ExitStack() as stack:
        endpoint = stack.enter_context(_router(kind, "router.json5", pki, tmp_path))
        daemon_file, viewer_file = _client_files("router.json5", tmp_path, pki, endpoint)
        stack.enter_context(_daemon_via(daemon_file, calibration, tmp_path))
        control = _ready_only(viewer_file)
        assert control.returncode == 0 and strict_json(control.stdout.splitlines()[0])[
            "event"] == "ready", control.stderr  # fmt: skip
        wrong = _login_file(tmp_path / "wrong.json5", endpoint, "gyrotherm-viewer",
                            "guessed-password", timeout_ms=2000)  # fmt: skip
        out = _ready_only(wrong)
        print(f"wrong password: exit {out.returncode}: {out.stderr.strip()}")
        assert out.returncode == 2 and out.stdout == "", (out.stdout, out.stderr)
        assert re.fullmatch(_OPEN_FAILED % re.escape(str(wrong)), out.stderr), out.stderr
        placeholder = tmp_path / "placeholder.json5"
        placeholder.write_text((DEPLOY_ZENOH / "client-of-router.json5").read_text())
        out = _ready_only(placeholder)
        assert out.returncode == 2 and out.stdout == ""
        assert "transport/auth/usrpwd/password is still the shipped placeholder" in out.stderr
