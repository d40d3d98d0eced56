"""``gyrotherm record`` as a process: SIGTERM finishes a readable MCAP; usage errors;
nothing imports mcap or foxglove unless ``record`` is asked for."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from mcap.reader import make_reader

from gyrotherm.client._record import record_main
from streamkit import cli_process, dead_port, stdout_after_sigterm

TIMEOUT_S = 60.0


def test_vehicle_and_client_paths_do_not_import_mcap_or_foxglove() -> None:
    code = ("import sys, json\n"
            "import gyrotherm.daemon, gyrotherm.client, gyrotherm.cli\n"
            "gyrotherm.cli.build_parser()\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('mcap', 'mcap_ros2', 'foxglove', 'rosbags', 'websockets'))))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=TIMEOUT_S)  # fmt: skip
    assert json.loads(out.stdout) == []
    assert "gyrotherm.client._record" not in out.stdout


def test_record_needs_a_sink(capsys) -> None:  # type: ignore[no-untyped-def]
    assert record_main(["--vehicle", "v", "--sensor", "s"]) == 2
    assert "--mcap" in capsys.readouterr().err


def test_sigterm_finishes_the_file(tmp_path: Path) -> None:
    """No daemon: record waits; SIGTERM ends it with a complete (readable) MCAP, exit 1
    (nothing recorded) and the JSON summary."""
    out = tmp_path / "x.mcap"
    with dead_port() as port, cli_process(
            "record", "--vehicle", "v", "--sensor", "s", "--connect", f"tcp/127.0.0.1:{port}",
            "--mcap", str(out), "--json", "--calibration-timeout-s", "0.2") as proc:
        assert proc.stderr is not None
        line = proc.stderr.readline()  # printed once subscribed
        assert "gyrotherm/v/s/*" in line and str(out) in line
        stdout = stdout_after_sigterm(proc, TIMEOUT_S)
    assert proc.returncode == 1
    summary = json.loads(stdout)
    assert summary["messages"] == {} and summary["angular_velocity_variance_dps2"] == [0, 0, 0]
    with out.open("rb") as f:
        s = make_reader(f).get_summary()
    assert s is not None
    assert {c.topic for c in s.channels.values()} == {
        f"/gyrotherm/s/{t}" for t in ("imu", "imu_raw", "temperature", "delta_t", "bias",
                                      "state", "health")}
    assert {x.name for x in s.schemas.values()} == {
        "sensor_msgs/msg/Imu", "sensor_msgs/msg/Temperature",
        "geometry_msgs/msg/Vector3Stamped", "diagnostic_msgs/msg/DiagnosticArray"}


def test_idle_timeout_ends_a_stream_that_went_silent(tmp_path: Path,
                                                     capsys) -> None:  # type: ignore[no-untyped-def]
    """A publisher sends health messages until record has one, then stops talking while
    its session stays up: record ends after --idle-timeout-s with exit 1, says why, and
    the MCAP holds what came before."""
    import threading
    import time

    from gyrotherm._zenoh import session_config
    from gyrotherm.codecs._wire import HealthMessage, StatusFlags, encode_health
    from streamkit import open_ephemeral

    session, endpoint = open_ephemeral(session_config(listen=["tcp/127.0.0.1:0"]))
    out, result, ready = tmp_path / "idle.mcap", {}, threading.Event()
    argv = ["--vehicle", "v", "--sensor", "s", "--connect", endpoint, "--mcap", str(out),
            "--json", "--calibration-timeout-s", "0.2", "--idle-timeout-s", "1.0"]
    rec = threading.Thread(target=lambda: result.update(
        code=record_main(argv, on_ready=lambda _port: ready.set())))
    with session:
        pub = session.declare_publisher("gyrotherm/v/s/health")
        rec.start()
        seq = 0
        while not ready.is_set() and seq < 2000:  # until record has a message (≤ 20 s)
            pub.put(encode_health(HealthMessage(seq, None, time.time(), 1.0, 0, 0, {},
                                                StatusFlags.NONE, "", 0)))
            seq += 1
            ready.wait(0.01)
        assert ready.is_set()
        silent_from = time.monotonic()
        rec.join(TIMEOUT_S)
        assert not rec.is_alive(), "record did not give up on a silent stream"
        waited = time.monotonic() - silent_from
    assert result["code"] == 1 and waited >= 1.0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["stopped_by"] == "idle" and summary["messages"]["/gyrotherm/s/health"] >= 1
    assert "no message for 1 s" in captured.err
    with out.open("rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == sum(
            summary["messages"].values())


def test_durations_and_counts_must_be_positive(capsys) -> None:  # type: ignore[no-untyped-def]
    for opt, value in (("--idle-timeout-s", "0"), ("--duration-s", "nan"), ("--count", "-1")):
        assert record_main(["--vehicle", "v", "--sensor", "s", "--mcap", "x.mcap",
                            opt, value]) == 2
        assert f"{opt} " in capsys.readouterr().err
