"""SocketcandServer against python-can's real socketcand client and raw sockets.

Truth: the socketcand protocol (linux-can/socketcand doc/protocol.md and
state_raw.c: ``< frame ID SEC.USEC DATA >`` with 3 hex digits for 11-bit ids,
8 for 29-bit ids, contiguous upper-case hex data) and frames computed here by
hand, independently of the module under test.
"""

from __future__ import annotations

import selectors
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator

import can
import pytest

from gyrotherm import ConfigError, DecodeError
from gyrotherm.sim._socketcand import (
    SocketcandServer,
    _peer_unread_bytes,
    encode_frame,
    parse_send,
)

TIMEOUT_S = 10.0


def expected_frame(i: int) -> tuple[int, bool, bytes, int]:
    """(id, extended, data, timestamp_us) of frame i: ids and lengths cover 0..8 bytes."""
    extended = i % 3 == 0
    arb = 0x1F000000 + 7 * i if extended else (0x7FF - i) % 0x800
    data = bytes((31 * i + k) % 256 for k in range(i % 9))
    return arb, extended, data, 1_700_000_000_000_000 + 2_003 * i


def make_frame(i: int) -> can.Message:
    arb, extended, data, ts_us = expected_frame(i)
    return can.Message(
        timestamp=ts_us / 1e6, arbitration_id=arb, is_extended_id=extended, data=data
    )


@pytest.fixture
def server() -> Iterator[SocketcandServer]:
    with SocketcandServer() as srv:
        yield srv


def connect(server: SocketcandServer) -> can.BusABC:
    bus = can.Bus(
        interface="socketcand",
        host="127.0.0.1",
        port=server.port,
        channel="vcan0",
        ignore_config=True,
    )
    return bus


def raw_client(server: SocketcandServer, *, rawmode: bool = True) -> socket.socket:
    """A socketcand client speaking the protocol by hand."""
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=TIMEOUT_S)
    assert sock.recv(64) == b"< hi >"
    sock.sendall(b"< open vcan0 >")
    assert sock.recv(64) == b"< ok >"
    if rawmode:
        sock.sendall(b"< rawmode >")
        assert sock.recv(64) == b"< ok >"
    return sock


def read_exactly(sock: socket.socket, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        assert chunk, f"connection closed after {out!r}"
        out += chunk
    return out


def assert_frame(msg: can.Message | None, i: int) -> None:
    arb, extended, data, ts_us = expected_frame(i)
    assert msg is not None, f"frame {i} missing"
    assert (msg.arbitration_id, msg.is_extended_id, bytes(msg.data), msg.dlc) == (
        arb,
        extended,
        data,
        len(data),
    ), f"frame {i}"
    assert round(msg.timestamp * 1e6) == ts_us, f"frame {i} timestamp"


def test_listens_on_loopback_by_default(server: SocketcandServer) -> None:
    host, port = server.address
    assert host == "127.0.0.1"
    assert 0 < port == server.port


def test_wire_format_matches_socketcand() -> None:
    # protocol.md example (ID 0x123, 11 22 33 44 at 23.424242 s), data contiguous as state_raw.c
    std = can.Message(
        timestamp=23.424242, arbitration_id=0x123, is_extended_id=False, data=b"\x11\x22\x33\x44"
    )
    assert encode_frame(std) == b"< frame 123 23.424242 11223344 >"
    ext = can.Message(timestamp=1.5, arbitration_id=0x1AAAAAAA, is_extended_id=True, data=b"")
    assert encode_frame(ext) == b"< frame 1AAAAAAA 1.500000  >"
    low = can.Message(timestamp=2.0000016, arbitration_id=0x5, is_extended_id=True, data=b"\xab")
    assert encode_frame(low) == b"< frame 00000005 2.000002 AB >"  # rounded to the µs


def test_parse_send_follows_protocol_examples() -> None:
    # protocol.md: "< send 123 0 >" and "< send 1AAAAAAA 2 1 F1 >"
    empty = parse_send("< send 123 0 >", channel="vcan0", timestamp_s=2.0)
    assert (empty.arbitration_id, empty.is_extended_id, bytes(empty.data)) == (0x123, False, b"")
    ext = parse_send("< send 1AAAAAAA 2 1 F1 >", channel="vcan0", timestamp_s=2.0)
    assert (ext.arbitration_id, ext.is_extended_id, bytes(ext.data)) == (
        0x1AAAAAAA,
        True,
        b"\x01\xf1",
    )
    assert ext.timestamp == 2.0 and ext.channel == "vcan0"


@pytest.mark.parametrize(
    "command",
    [
        "< send 123 2 1 >",
        "< send 800 0 >",
        "< send 123 9 1 2 3 4 5 6 7 8 9 >",
        "< send xyz 0 >",
        "< send 123 1 100 >",
        "< send >",
    ],
)
def test_parse_send_rejects_malformed(command: str) -> None:
    with pytest.raises(DecodeError, match="socketcand command"):
        parse_send(command, channel="vcan0", timestamp_s=0.0)


@pytest.mark.parametrize(
    ("kwargs", "why"),
    [
        ({"arbitration_id": 0x800, "is_extended_id": False}, "standard id"),
        ({"arbitration_id": 0x20000000, "is_extended_id": True, "check": False}, "extended id"),
        ({"arbitration_id": 1, "is_fd": True, "data": bytes(12)}, "classic"),
        ({"arbitration_id": 1, "is_remote_frame": True}, "classic"),
        ({"arbitration_id": 1, "timestamp": -1.0}, "timestamp"),
        ({"arbitration_id": 1, "timestamp": float("nan")}, "timestamp"),
    ],
)
def test_encode_rejects_what_socketcand_cannot_carry(kwargs: dict[str, object], why: str) -> None:
    msg = can.Message(**kwargs)  # type: ignore[arg-type]
    with pytest.raises(DecodeError, match=rf"frame 0x{msg.arbitration_id:X}: .*{why}"):
        encode_frame(msg)


def test_python_can_client_receives_frames_in_order(server: SocketcandServer) -> None:
    n = 300
    with connect(server) as bus:
        assert server.wait_for_clients(1, TIMEOUT_S)
        for i in range(n):
            server.send(make_frame(i))
        for i in range(n):
            msg = bus.recv(TIMEOUT_S)
            assert_frame(msg, i)
            assert msg is not None and msg.channel == "vcan0" and msg.is_rx
        assert server.flush(TIMEOUT_S)
    (stats,) = server.client_stats()
    assert (stats.frames_sent, stats.frames_dropped) == (n, 0)


def test_client_sent_frames_reach_server_recv(server: SocketcandServer) -> None:
    with connect(server) as bus:
        assert server.wait_for_clients(1, TIMEOUT_S)
        sent = [make_frame(i) for i in range(9)]  # 0..8 bytes, standard and extended ids
        for msg in sent:
            bus.send(msg)
        for i in range(len(sent)):
            got = server.recv(TIMEOUT_S)
            arb, extended, data, _ = expected_frame(i)
            assert got is not None
            assert (got.arbitration_id, got.is_extended_id, bytes(got.data)) == (
                arb,
                extended,
                data,
            )
            assert got.channel == "vcan0"
    assert server.recv(timeout_s=0) is None


def test_frames_between_clients_are_relayed(server: SocketcandServer) -> None:
    with connect(server) as a, connect(server) as b:
        assert server.wait_for_clients(2, TIMEOUT_S)
        a.send(make_frame(4))
        got = b.recv(TIMEOUT_S)
        arb, extended, data, _ = expected_frame(4)
        assert got is not None
        assert (got.arbitration_id, got.is_extended_id, bytes(got.data)) == (arb, extended, data)
        assert server.recv(TIMEOUT_S) is not None


def test_two_clients_both_receive(server: SocketcandServer) -> None:
    with connect(server) as a, connect(server) as b:
        assert server.wait_for_clients(2, TIMEOUT_S)
        assert server.client_count == 2
        for i in range(50):
            server.send(make_frame(i))
        for bus in (a, b):
            for i in range(50):
                assert_frame(bus.recv(TIMEOUT_S), i)


def test_client_disconnecting_mid_stream_does_not_stop_server(server: SocketcandServer) -> None:
    with connect(server) as stays:
        leaves = connect(server)
        assert server.wait_for_clients(2, TIMEOUT_S)
        for i in range(20):
            server.send(make_frame(i))
        for i in range(10):
            assert_frame(leaves.recv(TIMEOUT_S), i)
        leaves.shutdown()  # with 10 frames still unread
        for i in range(20, 40):
            server.send(make_frame(i))
        assert server.wait_until_disconnected(TIMEOUT_S, remaining=1)
        for i in range(40, 60):
            server.send(make_frame(i))
        for i in range(60):
            assert_frame(stays.recv(TIMEOUT_S), i)
        assert server.client_count == 1
        connected = sorted(s.connected for s in server.client_stats())
        assert connected == [False, True]
        with connect(server) as late:  # and still accepts clients
            assert server.wait_for_clients(2, TIMEOUT_S)
            server.send(make_frame(60))
            assert_frame(late.recv(TIMEOUT_S), 60)


def test_handshake_is_not_broken_by_frames_streaming(server: SocketcandServer) -> None:
    """python-can compares its whole first read with "< ok >": frames must not follow too soon."""
    stop = threading.Event()

    def produce() -> None:
        i = 0
        while not stop.is_set() and i < 2_000_000:
            for _ in range(100):
                server.send(make_frame(i % 1000))
                i += 1
            stop.wait(0.001)  # pacing, not synchronisation

    producer = threading.Thread(target=produce, daemon=True)
    producer.start()
    try:
        for _ in range(5):
            with connect(server) as bus:  # raises can.CanError if "< ok >" came glued to a frame
                msg = bus.recv(TIMEOUT_S)
                assert msg is not None and msg.channel == "vcan0"
    finally:
        stop.set()
        producer.join(TIMEOUT_S)


def test_protocol_commands_and_errors(server: SocketcandServer) -> None:
    sock = socket.create_connection(("127.0.0.1", server.port), timeout=TIMEOUT_S)
    with sock:
        assert sock.recv(64) == b"< hi >"
        sock.sendall(b"< rawmode >")  # before open: unknown in NO_BUS mode
        assert sock.recv(64) == b"< error unknown command >"
        sock.sendall(b"< open vcan0 >")
        assert sock.recv(64) == b"< ok >"
        sock.sendall(b"< echo >")
        assert sock.recv(64) == b"< echo >"
        sock.sendall(b"< subscribe 0 0 123 >")
        assert sock.recv(64) == b"< error unknown command >"
        sock.sendall(b"< rawmode >")
        assert sock.recv(64) == b"< ok >"
        assert server.wait_for_clients(1, TIMEOUT_S)
        server.send(make_frame(1))
        line = encode_frame(make_frame(1))
        assert read_exactly(sock, len(line)) == line
        sock.sendall(b"< bcmmode >")
        assert sock.recv(64) == b"< ok >"
        assert server.client_count == 0
    wrong = socket.create_connection(("127.0.0.1", server.port), timeout=TIMEOUT_S)
    with wrong:
        assert wrong.recv(64) == b"< hi >"
        wrong.sendall(b"< open can7 >")
        assert wrong.recv(64) == b"< error could not open bus >"
        assert wrong.recv(64) == b""  # and the server hangs up


def test_slow_client_is_bounded_and_counted() -> None:
    limit, n = 64, 3_072  # a multiple of the 32-frame chunks below
    with SocketcandServer(client_queue_frames=limit, client_sndbuf_bytes=4096) as server:
        stalled = socket.socket()
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stalled.settimeout(TIMEOUT_S)
        stalled.connect(("127.0.0.1", server.port))
        stalled.sendall(b"< open vcan0 >< rawmode >")
        assert read_exactly(stalled, 18) == b"< hi >< ok >< ok >"
        with stalled, connect(server) as fast:
            assert server.wait_for_clients(2, TIMEOUT_S)
            for first in range(0, n, 32):  # the fast client keeps up, the stalled one never reads
                for i in range(first, first + 32):
                    server.send(make_frame(i))
                for i in range(first, first + 32):
                    assert_frame(fast.recv(TIMEOUT_S), i)
            peer = "{}:{}".format(*stalled.getsockname()[:2])
            (slow,) = (s for s in server.client_stats() if s.peer == peer)
            (quick,) = (s for s in server.client_stats() if s.peer != peer)
            assert quick.frames_dropped == 0
            assert slow.frames_dropped > 0
            assert slow.frames_sent + slow.frames_dropped <= n
            assert n - slow.frames_sent - slow.frames_dropped <= 2 * limit  # queued + in flight


def test_too_many_clients_are_refused() -> None:
    with SocketcandServer(max_clients=1) as server, raw_client(server):
        extra = socket.create_connection(("127.0.0.1", server.port), timeout=TIMEOUT_S)
        with extra:
            assert extra.recv(64) == b"< error too many clients >"


def test_shutdown_is_idempotent_and_closes_clients() -> None:
    server = SocketcandServer().start()
    port = server.port
    sock = raw_client(server)
    with sock:
        assert server.wait_for_clients(1, TIMEOUT_S)
        server.shutdown()
        server.shutdown()
        assert server.is_shutdown
        assert sock.recv(64) == b""  # EOF: the server closed its end
    assert server.recv(timeout_s=None) is None  # returns at once when shut down
    assert list(server) == []
    server.send(make_frame(0))  # discarded, no error
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT_S).close()
    with pytest.raises(RuntimeError, match="shut down"):
        server.start()


def test_iterating_the_server_yields_client_frames(server: SocketcandServer) -> None:
    with connect(server) as bus:
        assert server.wait_for_clients(1, TIMEOUT_S)
        for i in range(3):
            bus.send(make_frame(i))
        got = []
        for msg in server:
            got.append((msg.arbitration_id, bytes(msg.data)))
            if len(got) == 3:
                break
    assert got == [(expected_frame(i)[0], expected_frame(i)[2]) for i in range(3)]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"port": 70000}, "port"),
        ({"port": -1}, "port"),
        ({"channel": ""}, "channel"),
        ({"channel": "a b"}, "channel"),
        ({"host": ""}, "host"),
        ({"client_queue_frames": 0}, "client_queue_frames"),
        ({"max_clients": 0}, "max_clients"),
    ],
)
def test_bad_options_name_the_field(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(ConfigError, match=rf"^{field}: "):
        SocketcandServer(**kwargs)  # type: ignore[arg-type]


def test_port_in_use_is_a_config_error(server: SocketcandServer) -> None:
    other = SocketcandServer(port=server.port)
    with pytest.raises(ConfigError, match=rf"127.0.0.1:{server.port}") as info:
        other.start()
    assert isinstance(info.value.__cause__, OSError)
    other.shutdown()


def _readline(proc: subprocess.Popen[str], timeout_s: float) -> str:
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        assert sel.select(timeout_s), "server subprocess printed no port"
    return proc.stdout.readline()


def test_cross_process_server_plays_demo_frames() -> None:
    n = 500
    code = (
        "from gyrotherm.sim._socketcand import main; "
        f"raise SystemExit(main(['--frames', '{n}', '--timeout-s', '{TIMEOUT_S}']))"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        port = int(_readline(proc, 30.0))
        bus = can.Bus(
            interface="socketcand", host="127.0.0.1", port=port, channel="vcan0", ignore_config=True
        )
        with bus:
            for i in range(n):  # documented demo_frame: computed here independently
                msg = bus.recv(TIMEOUT_S)
                assert msg is not None, f"frame {i} missing"
                data = bytes((i + k) % 256 for k in range(i % 9))
                arb = 0x1ABC0000 + i if i % 2 else i % 0x800
                assert (msg.arbitration_id, msg.is_extended_id, bytes(msg.data)) == (
                    arb,
                    i % 2 == 1,
                    data,
                )
                assert round(msg.timestamp * 1e6) == 1_700_000_000_000_000 + 1_000 * i + i % 1_000
        assert proc.wait(timeout=30.0) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        assert proc.stdout is not None
        proc.stdout.close()


def test_peer_unread_bytes_sees_what_the_peer_has_not_read() -> None:
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.create_connection(listener.getsockname(), timeout=TIMEOUT_S)
        conn, _ = listener.accept()
        with client, conn:
            server_port, client_port = conn.getsockname()[1], conn.getpeername()[1]
            if _peer_unread_bytes(server_port, client_port) is None:
                pytest.skip("no /proc/net/tcp entry for a loopback peer (not Linux?)")
            conn.sendall(b"< ok >")
            assert read_exactly(client, 2) == b"< "
            assert _peer_unread_bytes(server_port, client_port) == 4
            assert read_exactly(client, 4) == b"ok >"
            assert _peer_unread_bytes(server_port, client_port) == 0
