"""README "Consuming the rates outside Python": its record commands parse (the ``--ros2``
one into the topic its ``ros2 topic echo`` line names; ``test_ros2_router.py`` runs it),
its ROS 2 (rosbags) block runs on an MCAP that ``McapSink`` wrote, printing the rates in
rad/s, and the README's MCAP + Foxglove record line runs against a daemon as pasted (only
the ports changed: the machine's other tests own 7447 and 8765), its file read by the
README's block."""

from __future__ import annotations

import contextlib
import io
import math
import re
import shlex
from pathlib import Path

import pytest

from gyrotherm.client._channels import Fanout, McapSink
from gyrotherm.client._record import _parser, _ros_options
from gyrotherm.client._ros2 import check_names
from gyrotherm.codecs import Run
from gyrotherm.codecs._wire import RateMessage, StatusFlags
from gyrotherm.compensation import Calibration

README = Path(__file__).resolve().parents[2] / "README.md"


def _section() -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index("## Consuming the rates outside Python")
    return text[start:text.index("\n## ", start + 1)]


def test_the_record_command_parses() -> None:
    block = re.search(r"```sh\n(.*?)```", _section(), re.S)
    assert block
    line = block.group(1).replace("\\\n", " ").split("#")[0]
    argv = shlex.split(line)
    assert argv[:2] == ["gyrotherm", "record"]
    args = _parser().parse_args(argv[2:])
    assert args.mcap == "imu0.mcap" and args.foxglove_port == 8765 and args.sensor == "imu0"
    assert args.foxglove_host == "127.0.0.1"


def test_the_record_command_runs_and_the_block_reads_its_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, runs: list[Run],
        calibration: Calibration) -> None:
    import threading
    import uuid

    from gyrotherm.bus import open_bus
    from gyrotherm.client._record import record_main
    from gyrotherm.codecs import FrameEncoder
    from gyrotherm.daemon import Daemon, parse_config
    from streamkit import free_port, run_frames

    block = re.search(r"```sh\n(.*?)```", _section(), re.S)
    assert block
    argv = shlex.split(block.group(1).replace("\\\n", " ").split("#")[0])[2:]
    port, channel = free_port(), f"rm-{uuid.uuid4().hex[:8]}"
    argv = [a.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{port}") for a in argv]
    argv[argv.index("--foxglove-port") + 1] = "0"
    run = runs[0].slice(0, 50)
    monkeypatch.chdir(tmp_path)
    daemon = Daemon(parse_config({
        "vehicle": "veh01", "sensor": "imu0",
        "calibration": str(calibration.save(tmp_path / "cal.json")), "health_period_s": 0.2,
        "can": {"interface": "virtual", "channel": channel, "recv_timeout_s": 0.05},
        "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}, base_dir=tmp_path))
    thread = threading.Thread(target=daemon.run, daemon=True)
    thread.start()
    try:
        assert daemon.ready.wait(20.0)
        ready, result = threading.Event(), {}
        rec = threading.Thread(target=lambda: result.update(code=record_main(
            [*argv, "--count", str(len(run)), "-q"], on_ready=lambda _p: ready.set())))
        rec.start()
        assert ready.wait(20.0)
        with open_bus(interface="virtual", channel=channel) as bus:
            for msg in run_frames(run, FrameEncoder()):
                bus.send(msg)
        rec.join(60.0)
        assert not rec.is_alive() and result["code"] == 0
    finally:
        daemon.stop()
        thread.join(20.0)
    code = re.search(r"```python\n(.*?)```", _section(), re.S)
    assert code and (tmp_path / "imu0.mcap").exists()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code.group(1), "README.md", "exec"), {})
    assert len(out.getvalue().splitlines()) == len(run)


def test_the_ros2_live_command_parses() -> None:
    blocks = [b for b in re.findall(r"```sh\n(.*?)```", _section(), re.S) if "--ros2" in b]
    assert len(blocks) == 1
    lines = [ln.split("#")[0] for ln in blocks[0].replace("\\\n", " ").splitlines()]
    router, record, echo = lines
    assert shlex.split(router) == ["ros2", "run", "rmw_zenoh_cpp", "rmw_zenohd"]
    argv = shlex.split(record)
    assert argv[:2] == ["gyrotherm", "record"]
    args = _parser().parse_args(argv[2:])
    assert _ros_options(args) is None
    assert (args.ros2, args.ros_domain_id, args.ros_namespace) == (True, 0, "/")
    assert args.ros_node_name == "gyrotherm_bridge"
    topics = check_names(args.sensor, domain_id=0, namespace="/", node_name="gyrotherm_bridge")
    assert shlex.split(echo) == ["RMW_IMPLEMENTATION=rmw_zenoh_cpp", "ros2", "topic", "echo",
                                 topics[0]]  # fmt: skip


def test_the_ros2_block_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    block = re.search(r"```python\n(.*?)```", _section(), re.S)
    assert block
    monkeypatch.chdir(tmp_path)
    fan = Fanout([McapSink("imu0.mcap")], sensor="imu0")
    sent = [RateMessage(i, 100.0 + i * 0.25, 1.7e9 + i, (0.0, 0.0, 90.0 * i),
                        (0.0, 0.0, 1.0), (0.0, 0.0, 1.0 - 90.0 * i), StatusFlags.NONE)
            for i in range(3)]  # 0, 90, 180 °/s → 0, π/2, π rad/s
    for m in sent:
        fan.on_rate(m)
    fan.close()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block.group(1), "README.md", "exec"), {})
    lines = [ln.split() for ln in out.getvalue().splitlines()]
    # header stamps: the receive clock (1.7e9 + i s), record's default
    assert [(int(a), int(b)) for a, b, _, _ in lines] == [(1_700_000_000 + i, 0)
                                                           for i in range(3)]  # fmt: skip
    assert [float(z) for _, _, z, _ in lines] == pytest.approx([0.0, math.pi / 2, math.pi])
