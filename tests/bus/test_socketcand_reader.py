"""gyrotherm's socketcand reader against a hostile peer and the simulator's server.

Truth: the socketcand line ``< frame ID SEC.USEC DATA >`` (linux-can/socketcand
``state_raw.c``: ``%03X``/``%08X`` id, ``%ld.%06ld``, ``%02X`` bytes) written
by hand below with its decoded values, python-can's conventions (8-digit id:
extended; timestamp = the sender's SEC.USEC), and the reasons documented in
:mod:`gyrotherm.bus._socketcand_items`.
"""

from __future__ import annotations

import logging
import socket
import sys
import threading
import time
from pathlib import Path

import can
import pytest

from gyrotherm import BusError
from gyrotherm.bus import (
    TRANSPORT_ERROR,
    TRANSPORT_MALFORMED,
    TRANSPORT_OTHER,
    FrameSink,
    FrameSource,
    SocketcandBus,
    TransportItem,
    open_bus,
)
from gyrotherm.bus._socketcand_items import parse_frame
from gyrotherm.sim._socketcand import SocketcandServer, demo_frame

sys.path.insert(0, str(Path(__file__).resolve().parent))
from socketcandkit import WAIT_S, HostilePeer

GOOD_A = b"< frame 123 1700000000.000042 0102AB >"
A = (0x123, False, b"\x01\x02\xab", 3, 1700000000.000042)
GOOD_B = b"< frame 1ABCDEF0 1700000000.000043  >"  # no data: both spaces, as socketcand
B = (0x1ABCDEF0, True, b"", 0, 1700000000.000043)
MARGIN_S = 1.0  # scheduling slack on 2 shared cores


def fields(item: object) -> object:
    """A frame as (id, extended, data, dlc, timestamp); a transport item as its reason."""
    if isinstance(item, can.Message):
        return (item.arbitration_id, item.is_extended_id, bytes(item.data), item.dlc,
                item.timestamp)
    if isinstance(item, TransportItem):
        return item.reason
    return item


def connect(peer: HostilePeer, timeout_s: float = 2.0) -> SocketcandBus:
    bus = open_bus(interface="socketcand", channel="vcan0", host="127.0.0.1", port=peer.port,
                   handshake_timeout_s=timeout_s)
    assert isinstance(bus, SocketcandBus)
    return bus


def wait_lost(bus: SocketcandBus) -> None:
    """recv(0.2) until the bus says link_lost (bounded); every call returns None."""
    deadline = time.monotonic() + WAIT_S
    while not bus.link_lost and time.monotonic() < deadline:
        assert bus.recv(0.2) is None
    assert bus.link_lost


def read(bus: SocketcandBus, n: int) -> list[object]:
    got = [fields(bus.recv(WAIT_S)) for _ in range(n)]
    assert None not in got, got
    return got


BAD_ITEMS = {
    "non-hex id": (b"< frame ZZZ 1.000000 F4011EFB96000528 >", TRANSPORT_MALFORMED),
    "time stamp not a number": (b"< frame 123 17x0.00abc 0102 >", TRANSPORT_MALFORMED),
    "time stamp nan": (b"< frame 123 nan 0102 >", TRANSPORT_MALFORMED),
    "non-hex data": (b"< frame 123 1.000000 01G2 >", TRANSPORT_MALFORMED),
    "odd-length data": (b"< frame 123 1.000000 012 >", TRANSPORT_MALFORMED),
    "data over 8 bytes": (b"< frame 123 1.000000 010203040506070809 >", TRANSPORT_MALFORMED),
    "no data field": (b"< frame 123 1.000000 >", TRANSPORT_MALFORMED),
    "11-bit id above 0x7FF": (b"< frame 800 1.000000 01 >", TRANSPORT_MALFORMED),
    "5-digit id": (b"< frame 12345 1.000000 01 >", TRANSPORT_MALFORMED),
    "id with 0x": (b"< frame 0x1 1.000000 01 >", TRANSPORT_MALFORMED),
    "extra field": (b"< frame 123 1.000000 01 02 >", TRANSPORT_MALFORMED),
    "non-ASCII": (b"< frame 123 1.000000 0102\xc3\xa9\xff >", TRANSPORT_MALFORMED),
    "NUL": (b"< frame 123\x00 1.000000 01 >", TRANSPORT_MALFORMED),
    "empty item": (b"<>", TRANSPORT_MALFORMED),
    "oversized item": (b"< frame " + b"A" * 5000 + b" >", TRANSPORT_MALFORMED),
    "bytes outside < >": (b"garbage\x00\xff", TRANSPORT_MALFORMED),
    "truncated frame": (b"< frame 123 1700000000.0000", TRANSPORT_MALFORMED),
    "server error line": (b"< error unknown command >", TRANSPORT_ERROR),
    "CAN error frame report": (b"< error 004 1700000000.000000 >", TRANSPORT_ERROR),
    "ok after handshake": (b"< ok >", TRANSPORT_OTHER),
    "echo": (b"< echo >", TRANSPORT_OTHER),
}


@pytest.mark.parametrize("case", BAD_ITEMS)
def test_bad_item_is_one_transport_item_between_intact_frames(case: str) -> None:
    bad, reason = BAD_ITEMS[case]
    with HostilePeer([GOOD_A + bad + GOOD_B]) as peer, connect(peer) as bus:
        assert read(bus, 3) == [A, reason, B]
        assert bus.recv(0.05) is None  # nothing else: exactly one item for the bad bytes
        assert not bus.link_lost
        assert dict(bus.counts) == {reason: 1}


def test_items_split_across_tcp_writes_byte_by_byte() -> None:
    stream = GOOD_A + b"< error x >" + b"< frame 123 1.0" + GOOD_B + b" \r\n" + GOOD_A
    with HostilePeer([stream[i : i + 1] for i in range(len(stream))]) as peer, \
            connect(peer) as bus:
        assert read(bus, 5) == [A, TRANSPORT_ERROR, TRANSPORT_MALFORMED, B, A]


def test_open_item_then_eof_is_malformed_and_the_link_is_lost() -> None:
    with HostilePeer([GOOD_A, b"< frame 123 1.0"]) as peer, connect(peer) as bus:
        assert peer.sent.wait(WAIT_S)
        assert read(bus, 1) == [A]
        peer.vanish()
        assert read(bus, 1) == [TRANSPORT_MALFORMED]
        assert bus.link_lost and bus.recv(0.1) is None


@pytest.mark.parametrize("reset", [False, True], ids=["closed", "reset"])
def test_vanished_peer_waits_without_spinning(reset: bool) -> None:
    with HostilePeer([GOOD_A]) as peer, connect(peer) as bus:
        assert read(bus, 1) == [A]
        assert not bus.link_lost
        peer.vanish(reset=reset)
        wait_lost(bus)
        cpu0 = time.thread_time()
        for _ in range(5):
            t0 = time.monotonic()
            assert bus.recv(0.2) is None
            assert time.monotonic() - t0 >= 0.19  # waited its timeout: no busy loop
        assert time.thread_time() - cpu0 < 0.05
        with pytest.raises(BusError, match=rf"127\.0\.0\.1:{peer.port} channel 'vcan0'.*lost"):
            bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01"))


@pytest.mark.parametrize(
    ("script", "expected"),
    [
        ({"hi": None}, r"expected '< hi >' on connecting, got no answer within"),
        ({"open_reply": None}, r"expected '< ok >' to '< open vcan0 >', got no answer"),
        ({"raw_reply": None}, r"expected '< ok >' to '< rawmode >', got no answer"),
        ({"open_reply": b"< error could not open bus >"},
         r"expected '< ok >' to '< open vcan0 >', got b'< error could not open bus >'"),
        ({"hi": b"SSH-2.0-OpenSSH_9.6\r\n"}, r"expected '< hi >'.*no complete '< … >' item"),
        ({"hi": b"< hello >"}, r"expected '< hi >' on connecting, got b'< hello >'"),
    ],
    ids=["silent", "no-ok-to-open", "no-ok-to-rawmode", "error-to-open", "ssh", "wrong-word"],
)
def test_handshake_failures_are_bus_errors_within_the_timeout(
    script: dict[str, bytes | None], expected: str
) -> None:
    timeout_s = 0.5
    with HostilePeer([GOOD_A], **script) as peer:
        threads = set(threading.enumerate())
        t0 = time.monotonic()
        with pytest.raises(BusError, match=expected) as info:
            connect(peer, timeout_s)
        elapsed = time.monotonic() - t0
        assert elapsed < timeout_s + MARGIN_S
        assert f"127.0.0.1:{peer.port} channel 'vcan0'" in str(info.value)
        assert set(threading.enumerate()) <= threads  # no thread left behind


def test_peer_that_closes_during_handshake_is_a_bus_error() -> None:
    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]

    def hi_and_close() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.sendall(b"< hi >")  # then closes without answering '< open >'

    server = threading.Thread(target=hi_and_close)
    server.start()
    try:
        with pytest.raises(BusError, match=rf"127\.0\.0\.1:{port} channel 'vcan0': handshake:"
                           r" expected '< ok >' to '< open vcan0 >', but the peer closed"):
            SocketcandBus.connect("127.0.0.1", port, "vcan0", handshake_timeout_s=WAIT_S)
    finally:
        server.join(WAIT_S)
        listener.close()


def test_transport_items_are_logged_1_2_4_8_times(caplog: pytest.LogCaptureFixture) -> None:
    n = 1000
    with HostilePeer([b"< ok >" * n + GOOD_A]) as peer, connect(peer) as bus, \
            caplog.at_level(logging.DEBUG):
        assert read(bus, n + 1)[-1] == A
    assert dict(bus.counts) == {TRANSPORT_OTHER: n}
    lines = [r for r in caplog.records if r.name == "gyrotherm.bus.socketcand"]
    assert len(lines) == 10  # occurrences 1, 2, 4, …, 512
    assert all(r.levelno == logging.WARNING and "< ok >" in r.getMessage() for r in lines)
    assert not [r for r in caplog.records if r.name.startswith("can")]


def test_simulator_round_trip_is_bit_exact() -> None:
    """SocketcandServer (encode_frame) → SocketcandBus: ids, data and time stamps exact."""
    n = 3000
    with SocketcandServer() as server, open_bus(
        interface="socketcand", channel="vcan0", host="127.0.0.1", port=server.port
    ) as bus:
        assert isinstance(bus, SocketcandBus)
        assert isinstance(bus, FrameSource) and isinstance(bus, FrameSink)
        assert server.wait_for_clients(1, WAIT_S)
        for i in range(n):
            server.send(demo_frame(i))
        got = [bus.recv(WAIT_S) for _ in range(n)]
        assert bus.recv(0.05) is None
        assert not bus.counts
    for i, msg in enumerate(got):
        want = demo_frame(i)
        assert isinstance(msg, can.Message), (i, msg)
        assert fields(msg) == (want.arbitration_id, want.is_extended_id, bytes(want.data),
                               want.dlc, want.timestamp), i
        assert msg.channel == "vcan0" and msg.is_rx
        assert not (msg.is_error_frame or msg.is_remote_frame or msg.is_fd)


def test_send_reaches_the_simulator() -> None:
    frames = [
        can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"\x00\xff\x10"),
        can.Message(arbitration_id=0x1FFFFFFF, is_extended_id=True, data=b""),
        can.Message(arbitration_id=0x18FF0001, is_extended_id=True, data=bytes(range(8))),
    ]
    with SocketcandServer() as server, open_bus(
        interface="socketcand", channel="vcan0", host="127.0.0.1", port=server.port
    ) as bus:
        assert server.wait_for_clients(1, WAIT_S)
        for f in frames:
            bus.send(f, timeout_s=1.0)
        got = [server.recv(WAIT_S) for _ in frames]
    assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got if m] == [
        (f.arbitration_id, f.is_extended_id, bytes(f.data)) for f in frames
    ]
    assert server.rx_errors == 0


def test_shutdown_wakes_a_waiting_reader_and_is_idempotent() -> None:
    with HostilePeer([]) as peer:
        bus = connect(peer)
        result: list[object] = []
        reader = threading.Thread(target=lambda: result.append(bus.recv(None)))
        reader.start()
        bus.shutdown()
        reader.join(WAIT_S)
        assert not reader.is_alive() and result == [None]
        bus.shutdown()
        assert bus.is_shutdown and bus.recv(0) is None


def test_parsed_frame_is_a_complete_can_message() -> None:
    """The reader fills can.Message's slots itself (speed): every slot as the constructor."""
    msg = parse_frame(b"1ABCDEF0", b"1700000000.000042", b"0102AB", "vcan0")
    want = can.Message(timestamp=1700000000.000042, arbitration_id=0x1ABCDEF0,
                       is_extended_id=True, data=b"\x01\x02\xab", channel="vcan0", is_rx=True)
    assert type(msg) is can.Message
    slots = [s for s in can.Message.__slots__ if s != "__weakref__"]
    assert {s: getattr(msg, s) for s in slots} == {s: getattr(want, s) for s in slots}
    assert msg.equals(want) and isinstance(msg.data, bytearray)
