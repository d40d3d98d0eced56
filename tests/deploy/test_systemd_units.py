"""The systemd units, sysusers, modules-load and networkd files in deploy/.

Checks, with the tools of the installed systemd where they exist:

* ``systemd-analyze verify`` prints NOTHING for each unit (it exits 0 on
  unknown keys and unparsable values, so any output counts as a failure).
  ``verify`` also rejects an ExecStart= binary that does not exist, and
  /opt/gyrotherm/venv is not installed here: each unit is therefore verified
  as a temporary copy whose ExecStart= points at this venv's ``gyrotherm``
  script (or its python). The drop-in examples are verified the same way, as
  ``<unit>.d/*.conf`` next to the copy, where ``verify`` reads them.
* ``systemd-analyze security --offline=true`` rates every unit at an overall
  exposure of at most 2.0.
* The settings the deployment relies on are present (sd_notify + watchdog,
  user, directories, sandbox) — read from the files, after systemd.exec(5).
* ``systemd-sysusers --dry-run --root=<tmp>`` accepts the sysusers.d file.
* The networkd files parse as INI and use only keys documented in
  systemd.network(5) / systemd.netdev(5) / systemd.link(5); where
  systemd-networkd is installed, the keys are also looked up in its own
  configuration-parser table (the ``Section.Key`` strings of its gperf table),
  since networkd has no verify mode.
* Under strace, the dependency stack (numpy, python-can, cantools, filterpy,
  msgpack, zenoh with deploy/zenoh/peer-vehicle.json5, gyrotherm) runs with
  every system call outside the unit's SystemCallFilter= failing with EPERM
  (SystemCallErrorNumber=EPERM), with the kernel's PR_SET_MDWE
  refuse-exec-gain (the kernel counterpart of MemoryDenyWriteExecute=), using
  only the unit's RestrictAddressFamilies=, and touching /proc only inside the
  ProcSubset=pid view. AF_CAN cannot be exercised here (no SocketCAN).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
UNITS = sorted((DEPLOY / "systemd").glob("*.service"))
INSTALLED_EXEC = "/opt/gyrotherm/venv/bin/gyrotherm"
MAX_EXPOSURE = 2.0

SYSTEMD_ANALYZE = shutil.which("systemd-analyze")
needs_analyze = pytest.mark.skipif(
    SYSTEMD_ANALYZE is None, reason="systemd-analyze is not installed"
)

Ini = dict[str, list[tuple[str, str]]]


def parse_ini(path: Path) -> Ini:
    """systemd-style INI: sections of (key, value) pairs, repeated keys kept."""
    sections: Ini = {}
    current: str | None = None
    for number, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        assert not line.endswith("\\"), f"{path.name}:{number}: no continuation lines"
        if line.startswith("[") and line.endswith("]"):
            current = line[1:-1]
            sections.setdefault(current, [])
            continue
        key, sep, value = line.partition("=")
        assert sep, f"{path.name}:{number}: not KEY=VALUE: {line!r}"
        assert current is not None, f"{path.name}:{number}: key outside a section"
        sections[current].append((key.strip(), value.strip()))
    return sections


def values(ini: Ini, section: str, key: str) -> list[str]:
    return [v for k, v in ini.get(section, []) if k == key]


def one(ini: Ini, section: str, key: str) -> str:
    found = values(ini, section, key)
    assert len(found) == 1, f"[{section}] {key}= set {len(found)} times"
    return found[0]


def _local_executable() -> str:
    script = Path(sys.executable).parent / "gyrotherm"
    return str(script) if script.exists() else sys.executable


def _local_copy(unit: Path, directory: Path, *, with_dropins: bool = False) -> Path:
    """The unit with ExecStart= pointing at an executable that exists here."""
    text = unit.read_text(encoding="utf-8")
    assert INSTALLED_EXEC in text
    copy = directory / unit.name
    copy.write_text(text.replace(INSTALLED_EXEC, _local_executable()), encoding="utf-8")
    dropins = unit.parent / f"{unit.name}.d"
    if with_dropins and dropins.is_dir():
        target = directory / dropins.name
        target.mkdir()
        for example in sorted(dropins.glob("*.conf.example")):
            shutil.copy(example, target / example.name.removesuffix(".example"))
    return copy


def _analyze(*args: str) -> subprocess.CompletedProcess[str]:
    assert SYSTEMD_ANALYZE is not None
    return subprocess.run(
        [SYSTEMD_ANALYZE, *args], capture_output=True, text=True, timeout=120, check=False
    )


def _exposure(unit_copy: Path) -> float:
    done = _analyze("security", "--offline=true", "--no-pager", str(unit_copy))
    assert done.returncode == 0, done.stderr
    match = re.search(
        rf"Overall exposure level for {re.escape(unit_copy.name)}: (\d+\.\d+)", done.stdout
    )
    assert match, done.stdout
    return float(match.group(1))


def test_expected_units_exist() -> None:
    assert {unit.name for unit in UNITS} == {
        "gyrotherm.service",
        "gyrotherm-sim.service",
        "gyrotherm-sim-socketcand.service",
    }


@needs_analyze
@pytest.mark.parametrize("unit", UNITS, ids=lambda p: p.name)
def test_systemd_analyze_verify_prints_nothing(unit: Path, tmp_path: Path) -> None:
    copy = _local_copy(unit, tmp_path, with_dropins=True)
    done = _analyze("verify", "--no-pager", str(copy))
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


@needs_analyze
def test_verify_reports_bad_keys_so_the_check_can_fail(tmp_path: Path) -> None:
    # The check above relies on verify printing something for a bad file.
    copy = _local_copy(DEPLOY / "systemd" / "gyrotherm.service", tmp_path)
    text = copy.read_text(encoding="utf-8")
    copy.write_text(text.replace("WatchdogSec=5s", "WatchdogSec=5s\nWatchdogSek=5s"))
    done = _analyze("verify", "--no-pager", str(copy))
    assert "WatchdogSek" in done.stdout + done.stderr


@needs_analyze
@pytest.mark.parametrize("unit", UNITS, ids=lambda p: p.name)
def test_security_exposure_at_most_2(unit: Path, tmp_path: Path) -> None:
    assert _exposure(_local_copy(unit, tmp_path)) <= MAX_EXPOSURE


@needs_analyze
def test_security_exposure_with_vehicle_dropins(tmp_path: Path) -> None:
    copy = _local_copy(DEPLOY / "systemd" / "gyrotherm.service", tmp_path, with_dropins=True)
    dropins = sorted(p.name for p in (tmp_path / "gyrotherm.service.d").iterdir())
    assert dropins == ["10-vehicle-network.conf", "20-can0-device.conf"]
    assert _exposure(copy) <= MAX_EXPOSURE


COMMON_SANDBOX = {
    "NoNewPrivileges": "yes",
    "CapabilityBoundingSet": "",
    "PrivateUsers": "yes",
    "ProtectSystem": "strict",
    "ProtectHome": "yes",
    "PrivateTmp": "yes",
    "PrivateDevices": "yes",
    "DevicePolicy": "closed",
    "PrivateNetwork": "no",
    "ProtectKernelTunables": "yes",
    "ProtectKernelModules": "yes",
    "ProtectKernelLogs": "yes",
    "ProtectControlGroups": "yes",
    "ProtectClock": "yes",
    "ProtectHostname": "yes",
    "ProtectProc": "invisible",
    "ProcSubset": "pid",
    "RestrictNamespaces": "yes",
    "RestrictRealtime": "yes",
    "RestrictSUIDSGID": "yes",
    "LockPersonality": "yes",
    "MemoryDenyWriteExecute": "yes",
    "SystemCallArchitectures": "native",
    "SystemCallErrorNumber": "EPERM",
    "UMask": "0077",
    "KeyringMode": "private",
    "RemoveIPC": "yes",
    "IPAddressDeny": "any",
    "StandardOutput": "journal",
}


@pytest.mark.parametrize("unit", UNITS, ids=lambda p: p.name)
def test_common_sandbox(unit: Path) -> None:
    ini = parse_ini(unit)
    for key, want in COMMON_SANDBOX.items():
        assert one(ini, "Service", key) == want, key
    assert values(ini, "Service", "SystemCallFilter")[0] == "@system-service"
    # the daemon restarts when it fails; a bench player also after a run ends (exit 0)
    want = "always" if unit.name.startswith("gyrotherm-sim") else "on-failure"
    assert one(ini, "Service", "Restart") == want
    assert one(ini, "Service", "ExecStart").startswith(INSTALLED_EXEC + " ")


def test_daemon_unit_contract() -> None:
    ini = parse_ini(DEPLOY / "systemd" / "gyrotherm.service")
    expected = {
        "Type": "notify",
        "NotifyAccess": "main",
        "WatchdogSec": "5s",
        "ExecReload": "/bin/kill -HUP $MAINPID",
        "User": "gyrotherm",
        "Group": "gyrotherm",
        "DynamicUser": "no",
        "ConfigurationDirectory": "gyrotherm",
        "StateDirectory": "gyrotherm",
        "ExecStart": f"{INSTALLED_EXEC} run --config /etc/gyrotherm/gyrotherm.toml",
    }
    for key, want in expected.items():
        assert one(ini, "Service", key) == want, key
    assert one(ini, "Service", "RestartSec")
    assert set(one(ini, "Service", "RestrictAddressFamilies").split()) == {
        "AF_CAN",
        "AF_INET",
        "AF_INET6",
        "AF_UNIX",
        "AF_NETLINK",
    }
    assert values(ini, "Service", "IPAddressAllow") == ["localhost"]
    # No CAN device dependency in the base unit (benches without SocketCAN);
    # the vehicle drop-in adds it for can0, the channel of gyrotherm.toml.
    assert "can0" not in " ".join(values(ini, "Unit", "After") + values(ini, "Unit", "Wants"))
    dropin = parse_ini(DEPLOY / "systemd" / "gyrotherm.service.d" / "20-can0-device.conf.example")
    device = "sys-subsystem-net-devices-can0.device"
    assert one(dropin, "Unit", "Wants") == one(dropin, "Unit", "After") == device
    network = parse_ini(
        DEPLOY / "systemd" / "gyrotherm.service.d" / "10-vehicle-network.conf.example"
    )
    assert len(values(network, "Service", "IPAddressAllow")) == 1
    # The static user comes from sysusers.d with the same name.
    sysusers = (DEPLOY / "sysusers.d" / "gyrotherm.conf").read_text(encoding="utf-8")
    assert re.search(r"^u\s+gyrotherm\s", sysusers, re.MULTILINE)


def test_simulator_units() -> None:
    vcan = parse_ini(DEPLOY / "systemd" / "gyrotherm-sim.service")
    device = "sys-subsystem-net-devices-vcan0.device"
    assert one(vcan, "Unit", "BindsTo") == device
    assert device in one(vcan, "Unit", "After").split()
    assert one(vcan, "Service", "ExecStart").split()[1:] == [
        "sim",
        "stream",
        "--interface",
        "socketcan",
        "--channel",
        "vcan0",
    ]
    assert "AF_INET" not in one(vcan, "Service", "RestrictAddressFamilies")
    tcp = parse_ini(DEPLOY / "systemd" / "gyrotherm-sim-socketcand.service")
    argv = one(tcp, "Service", "ExecStart").split()
    assert argv[1:5] == ["sim", "stream", "--interface", "socketcand"]
    assert argv[argv.index("--host") + 1] == "127.0.0.1"
    assert argv[argv.index("--port") + 1] == "29536"
    assert values(tcp, "Service", "IPAddressAllow") == ["localhost"]
    assert "AF_CAN" not in one(tcp, "Service", "RestrictAddressFamilies")


@pytest.mark.skipif(shutil.which("systemd-sysusers") is None, reason="no systemd-sysusers")
def test_sysusers_dry_run(tmp_path: Path) -> None:
    (tmp_path / "etc").mkdir()
    done = subprocess.run(
        [
            "systemd-sysusers",
            "--dry-run",
            f"--root={tmp_path}",
            str(DEPLOY / "sysusers.d" / "gyrotherm.conf"),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert "Creating group 'gyrotherm'" in output
    assert "Creating user 'gyrotherm'" in output
    assert not re.search(r"warn|fail|invalid|ignor", output, re.IGNORECASE), output


def test_modules_load_lists_socketcan_raw() -> None:
    lines = (DEPLOY / "modules-load.d" / "gyrotherm-can.conf").read_text().splitlines()
    modules = [line.strip() for line in lines if line.strip() and line.strip()[0] not in "#;"]
    assert modules == ["can", "can_raw"]


# ------------------------------------------------------------------- networkd
# Keys used here, as documented in systemd.network(5), systemd.netdev(5) and
# systemd.link(5) (systemd 252; TransmitQueueLength= since 248).
DOCUMENTED_KEYS = {
    ".network": {
        "Match": {"Name", "Type", "Kind", "Driver", "Path", "MACAddress"},
        "Link": {"RequiredForOnline", "ActivationPolicy", "MTUBytes", "Unmanaged"},
        "CAN": {
            "BitRate",
            "SamplePoint",
            "RestartSec",
            "Termination",
            "BusErrorReporting",
            "ListenOnly",
            "Loopback",
            "OneShot",
            "TripleSampling",
            "DataBitRate",
            "DataSamplePoint",
            "FDMode",
            "FDNonISO",
        },
    },
    ".netdev": {"NetDev": {"Name", "Kind", "Description", "MTUBytes"}},
    ".link": {
        "Match": {"OriginalName", "MACAddress", "Path", "Driver", "Type", "Kind"},
        "Link": {"TransmitQueueLength", "Name", "NamePolicy", "MTUBytes", "Description"},
    },
}
NETWORKD = Path("/usr/lib/systemd/systemd-networkd")
NETWORKD_FILES = sorted((DEPLOY / "networkd").iterdir())


def _keys(ini: Ini) -> Iterable[tuple[str, str]]:
    for section, pairs in ini.items():
        for key, _value in pairs:
            yield section, key


def test_networkd_files_present() -> None:
    assert {path.name for path in NETWORKD_FILES} == {
        "60-can0.link",
        "80-can0.network",
        "80-vcan0.netdev",
        "80-vcan0.network",
    }


@pytest.mark.parametrize("path", NETWORKD_FILES, ids=lambda p: p.name)
def test_networkd_keys_are_documented(path: Path) -> None:
    allowed = DOCUMENTED_KEYS[path.suffix]
    ini = parse_ini(path)
    assert ini, path.name
    for section, key in _keys(ini):
        assert key in allowed.get(section, set()), f"{path.name}: [{section}] {key}="


@pytest.mark.skipif(not NETWORKD.exists(), reason="systemd-networkd is not installed")
def test_networkd_knows_every_key() -> None:
    table = set(
        re.findall(rb"\b(?:Match|Link|CAN|NetDev|Network)\.[A-Za-z0-9]+", NETWORKD.read_bytes())
    )
    assert b"CAN.BitRate" in table  # the table really is there
    for path in NETWORKD_FILES:
        if path.suffix == ".link":
            continue  # .link files are read by udev, not networkd
        for section, key in _keys(parse_ini(path)):
            assert f"{section}.{key}".encode() in table, f"{path.name}: [{section}] {key}="


def test_networkd_values() -> None:
    can0 = parse_ini(DEPLOY / "networkd" / "80-can0.network")
    assert one(can0, "Match", "Name") == "can0"
    assert one(can0, "CAN", "BitRate") == "500000"
    assert one(can0, "CAN", "RestartSec") == "100ms"
    vcan = parse_ini(DEPLOY / "networkd" / "80-vcan0.netdev")
    assert (one(vcan, "NetDev", "Name"), one(vcan, "NetDev", "Kind")) == ("vcan0", "vcan")
    assert one(parse_ini(DEPLOY / "networkd" / "80-vcan0.network"), "Match", "Name") == "vcan0"
    link = parse_ini(DEPLOY / "networkd" / "60-can0.link")
    assert one(link, "Match", "OriginalName") == "can0"


# -------------------------------------------- sandbox emulation under strace
PROBE = r"""
import ctypes, json, sys, threading
mdwe = False
if sys.argv[1] == "mdwe":
    libc = ctypes.CDLL(None, use_errno=True)
    PR_SET_MDWE, PR_MDWE_REFUSE_EXEC_GAIN = 65, 1
    mdwe = libc.prctl(PR_SET_MDWE, PR_MDWE_REFUSE_EXEC_GAIN, 0, 0, 0) == 0
import numpy, can, cantools, filterpy.kalman, msgpack, zenoh
import gyrotherm, gyrotherm.compensation, gyrotherm.estimators, gyrotherm.codecs
import gyrotherm.daemon
numpy.linalg.inv(numpy.eye(4) * 2.0)
config = zenoh.Config.from_file(sys.argv[2])
config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
session = zenoh.open(config)
got = threading.Event()
sub = session.declare_subscriber("gyrotherm/v/imu0/rate", lambda s: got.set())
qbl = session.declare_queryable(
    "gyrotherm/v/imu0/calibration", lambda q: q.reply(q.key_expr, b"{}")
)
session.put("gyrotherm/v/imu0/rate", msgpack.packb({"rate_dps": [0.1, 0.2, 0.3]}))
received = got.wait(10)
replies = sum(1 for r in session.get("gyrotherm/v/imu0/calibration") if r.ok is not None)
session.close()
print(json.dumps({"mdwe": mdwe, "received": received, "replies": replies}))
"""


TOLERATED_EPERM = {
    # OpenBLAS (numpy) asks for a NUMA memory policy on its buffers and
    # ignores the result: @resources stays denied.
    "mbind",
}


def _filter_members(group: str, cache: dict[str, set[str]]) -> set[str]:
    if not group.startswith("@"):
        return {group}
    if group not in cache:
        done = _analyze("syscall-filter", "--no-pager", group)
        assert done.returncode == 0, done.stderr
        members: set[str] = set()
        for line in done.stdout.splitlines()[1:]:
            item = line.strip()
            if item and not item.startswith("#"):
                members |= _filter_members(item, cache)
        cache[group] = members
    return cache[group]


def allowed_syscalls(ini: Ini) -> set[str]:
    """The allow list that SystemCallFilter= lines build (systemd.exec(5))."""
    lines = values(ini, "Service", "SystemCallFilter")
    assert lines and not lines[0].startswith("~"), "expected an allow list first"
    cache: dict[str, set[str]] = {}
    allowed: set[str] = set()
    for line in lines:
        deny = line.startswith("~")
        names = set().union(*(_filter_members(n, cache) for n in line.lstrip("~").split()))
        allowed = allowed - names if deny else allowed | names
    return allowed


@needs_analyze
@pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")
def test_dependency_stack_runs_inside_the_units_sandbox(tmp_path: Path) -> None:
    ini = parse_ini(DEPLOY / "systemd" / "gyrotherm.service")
    allowed = allowed_syscalls(ini)
    assert {"read", "openat", "socket", "sendmsg"} <= allowed
    assert "mbind" not in allowed and "setuid" not in allowed
    families = set(one(ini, "Service", "RestrictAddressFamilies").split())
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE, encoding="utf-8")
    trace = tmp_path / "trace.txt"
    inject = "!" + ",".join(f"?{name}" for name in sorted(allowed))
    mode = "mdwe" if one(ini, "Service", "MemoryDenyWriteExecute") == "yes" else "plain"
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    done = subprocess.run(
        [
            "strace", "-f", "-qq", "-o", str(trace), "-e", "trace=all",
            "-e", f"inject={inject}:error=EPERM",
            sys.executable, str(probe), mode, str(DEPLOY / "zenoh" / "peer-vehicle.json5"),
        ],
        capture_output=True, text=True, timeout=120, check=False, cwd=tmp_path, env=env,
    )  # fmt: skip
    if "PTRACE" in done.stderr and not trace.exists():
        pytest.skip(f"strace cannot trace here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["received"] is True and result["replies"] == 1
    lines = trace.read_text(encoding="utf-8", errors="replace").splitlines()
    injected = re.compile(r"^\d+\s+(?:<\.\.\. (\w+) resumed>|(\w+)\().*\(INJECTED\)$")
    blocked = {m.group(1) or m.group(2) for line in lines if (m := injected.match(line))}
    # Calls outside the allow list were answered EPERM and the probe still
    # worked. Only reviewed ones may happen: a new one means a dependency now
    # needs a call the unit forbids (check it, then allow it or list it here).
    assert blocked <= TOLERATED_EPERM, blocked - TOLERATED_EPERM
    used_families = set(re.findall(r"\bsocket\((AF_\w+)", "\n".join(lines)))
    assert used_families <= families, used_families - families
    proc_opened = {
        m.group(1)
        for line in lines
        if (m := re.search(r'open(?:at)?\([^"]*"(/proc/[^"]*)"', line)) and " = -1 " not in line
    }
    outside_subset = {
        p for p in proc_opened if not re.match(r"/proc/(self|thread-self|\d+)(/|$)", p)
    }
    assert not outside_subset, outside_subset
    if not result["mdwe"]:
        pytest.xfail("kernel without PR_SET_MDWE (< 6.3): W^X part not exercised")


# ---------------------------------------------- example daemon configurations
def test_bench_configs_match_the_simulator_units() -> None:
    configs = {
        path.name: tomllib.loads(path.read_text()) for path in (DEPLOY / "config").glob("*.toml")
    }
    assert set(configs) == {
        "gyrotherm.toml",
        "gyrotherm-bench-vcan0.toml",
        "gyrotherm-bench-socketcand.toml",
    }
    assert configs["gyrotherm.toml"]["can"] == {"interface": "socketcan", "channel": "can0"}
    sim = one(parse_ini(DEPLOY / "systemd" / "gyrotherm-sim.service"), "Service", "ExecStart")
    vcan = configs["gyrotherm-bench-vcan0.toml"]["can"]
    assert f"--interface {vcan['interface']} --channel {vcan['channel']}" in sim
    tcp_argv = one(
        parse_ini(DEPLOY / "systemd" / "gyrotherm-sim-socketcand.service"), "Service", "ExecStart"
    ).split()
    tcp = configs["gyrotherm-bench-socketcand.toml"]["can"]
    for flag, key in (("--interface", "interface"), ("--host", "host"), ("--channel", "channel")):
        assert tcp_argv[tcp_argv.index(flag) + 1] == tcp[key]
    assert int(tcp_argv[tcp_argv.index("--port") + 1]) == tcp["port"]
    for config in configs.values():
        assert config["calibration"].startswith("/var/lib/gyrotherm/")
