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
        f"/gyrotherm/s/{t}" for t in ("imu", "imu_raw", "temperature", "state", "health")}
    assert {x.name for x in s.schemas.values()} == {
        "sensor_msgs/msg/Imu", "sensor_msgs/msg/Temperature", "gyrotherm.State",
        "gyrotherm.Health"}
