"""Frame sources/sinks: python-can buses and the socketcand server are interchangeable."""

from __future__ import annotations

import itertools
import logging
import socket

import can
import pytest

from gyrotherm import ConfigError
from gyrotherm.bus import BusAdapter, FrameSink, FrameSource, open_bus
from gyrotherm.sim._socketcand import SocketcandServer
from streamkit import dead_port

TIMEOUT_S = 10.0
_channels = itertools.count()


def virtual_channel() -> str:
    return f"gt-bus-{next(_channels)}"  # python-can virtual channels are process-global


def frame(i: int) -> can.Message:
    extended = i % 2 == 1
    return can.Message(
        timestamp=1_000.0 + i / 8,
        arbitration_id=0x18FF0000 + i if extended else 0x100 + i,
        is_extended_id=extended,
        data=bytes(range(i % 9)),
    )


def same(a: object, b: can.Message) -> bool:
    return isinstance(a, can.Message) and (a.arbitration_id, a.is_extended_id, bytes(a.data)) == (
        b.arbitration_id,
        b.is_extended_id,
        bytes(b.data),
    )


def pump(source: FrameSource, sink: FrameSink, n: int) -> int:
    """Code written only against the interfaces: copy n frames from source to sink."""
    copied = 0
    for msg in source:
        sink.send(msg)
        copied += 1
        if copied == n:
            break
    return copied


def test_virtual_bus_adapter_round_trip() -> None:
    channel = virtual_channel()
    with (
        open_bus(interface="virtual", channel=channel) as a,
        open_bus(interface="virtual", channel=channel) as b,
    ):
        assert isinstance(a, FrameSource) and isinstance(a, FrameSink)
        for i in range(9):
            a.send(frame(i))
        for i in range(9):
            assert same(b.recv(TIMEOUT_S), frame(i))
        assert a.recv(timeout_s=0) is None  # own frames are not echoed by default
    assert a.is_shutdown and b.is_shutdown


def test_receive_own_messages_is_passed_to_python_can() -> None:
    with open_bus(interface="virtual", channel=virtual_channel(), receive_own_messages=True) as a:
        a.send(frame(3))
        assert same(a.recv(TIMEOUT_S), frame(3))


def test_shutdown_is_idempotent_and_stops_iteration() -> None:
    bus = can.Bus(interface="virtual", channel=virtual_channel(), receive_own_messages=True)
    adapter = BusAdapter(bus)
    assert adapter.bus is bus
    adapter.send(frame(1))
    adapter.send(frame(2))
    got = []
    for msg in adapter:
        got.append(msg)
        if len(got) == 2:
            adapter.shutdown()  # the loop then ends on its own
    assert [m.arbitration_id for m in got] == [frame(1).arbitration_id, frame(2).arbitration_id]
    adapter.shutdown()
    assert adapter.is_shutdown and adapter.recv(timeout_s=0) is None


def test_socketcand_bus_and_server_interchange_with_virtual() -> None:
    """virtual bus → pump → socketcand server → gyrotherm's client → pump → virtual bus."""
    n = 40
    channel = virtual_channel()
    with (
        SocketcandServer() as server,
        open_bus(interface="virtual", channel=channel) as producer,
        open_bus(interface="virtual", channel=channel) as tap,
        open_bus(
            interface="socketcand", channel="vcan0", host="127.0.0.1", port=server.port
        ) as remote,
    ):
        assert server.wait_for_clients(1, TIMEOUT_S)
        for i in range(n):
            producer.send(frame(i))
        assert pump(tap, server, n) == n  # python-can virtual bus as source, server as sink
        for i in range(n):  # (python-can's virtual bus restamps frames: timestamps not compared)
            assert same(remote.recv(TIMEOUT_S), frame(i))
        remote.send(frame(5))  # and the other way: client → server as a source
        assert pump(server, producer, 1) == 1
        assert same(tap.recv(TIMEOUT_S), frame(5))


def test_socketcand_frames_split_across_reads_log_nothing(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """python-can's client warned on every read that ended mid-frame; ours is silent."""
    with (
        SocketcandServer() as server,
        open_bus(
            interface="socketcand", channel="vcan0", host="127.0.0.1", port=server.port
        ) as bus,
        caplog.at_level(logging.WARNING),
    ):
        assert server.wait_for_clients(1, TIMEOUT_S)
        for i in range(500):  # ~20 kB: TCP splits frames across reads
            server.send(frame(i))
        for i in range(500):
            assert same(bus.recv(TIMEOUT_S), frame(i))
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def _af_can_available() -> bool:
    try:
        socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except (OSError, AttributeError):
        return False
    return True


@pytest.mark.skipif(_af_can_available(), reason="this kernel supports AF_CAN sockets")
def test_socketcan_is_a_clear_config_error_without_af_can() -> None:
    with pytest.raises(ConfigError) as info:
        open_bus(interface="socketcan", channel="can0", bitrate=500_000)
    text = str(info.value)
    assert "interface 'socketcan', channel 'can0'" in text
    assert "SocketCAN is unavailable on this machine" in text
    assert "socketcand" in text  # says what to use instead
    assert isinstance(info.value.__cause__, OSError)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"interface": "pcan", "channel": "can0"}, "interface"),
        ({"interface": "virtual", "channel": ""}, "channel"),
        ({"interface": "virtual", "channel": "x" * 17}, "channel"),
        ({"interface": "virtual", "channel": "v", "bitrate": 0}, "bitrate"),
        ({"interface": "virtual", "channel": "v", "bitrate": True}, "bitrate"),
        ({"interface": "virtual", "channel": "v", "host": "127.0.0.1"}, "host"),
        ({"interface": "socketcan", "channel": "can0", "port": 29536}, "port"),
        ({"interface": "socketcand", "channel": "vcan0", "port": 29536}, "host"),
        ({"interface": "socketcand", "channel": "vcan0", "host": "127.0.0.1"}, "port"),
        ({"interface": "socketcand", "channel": "vcan0", "host": "h", "port": 65536}, "port"),
        ({"interface": "virtual", "channel": "v", "handshake_timeout_s": 1.0},
         "handshake_timeout_s"),
        ({"interface": "socketcand", "channel": "vcan0", "host": "h", "port": 1,
          "handshake_timeout_s": 0}, "handshake_timeout_s"),
        ({"interface": "socketcand", "channel": "vcan0", "host": "h", "port": 1,
          "handshake_timeout_s": float("nan")}, "handshake_timeout_s"),
        (
            {
                "interface": "socketcand",
                "channel": "vcan0",
                "host": "h",
                "port": 1,
                "receive_own_messages": True,
            },
            "receive_own_messages",
        ),
    ],
)
def test_bad_options_name_the_field(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(ConfigError, match=rf"^{field}: .*got "):
        open_bus(**kwargs)  # type: ignore[arg-type]


def test_socketcand_without_a_server_fails_at_once_without_python_can_retrying(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """python-can retries a refused connection in a busy loop for 10 s (one warning per
    attempt); the daemon reopens a silent bus from its processing loop, so open_bus
    must give up after one refused probe instead."""
    caplog.set_level(logging.DEBUG, logger="can")
    with dead_port() as port, pytest.raises(ConfigError) as info:
        open_bus(interface="socketcand", channel="vcan0", host="127.0.0.1", port=port)
    assert f"127.0.0.1:{port}" in str(info.value) and "no socketcand server" in str(info.value)
    assert isinstance(info.value.__cause__, ConnectionRefusedError)
    assert not [r for r in caplog.records if "connect" in r.getMessage().lower()]
