"""sd_notify client against a real AF_UNIX SOCK_DGRAM notify socket.

The expected datagrams are spelled out from sd_notify(3): newline-separated
KEY=VALUE assignments in one datagram. The receiving socket enables
SO_PASSCRED, as systemd does, so the kernel-attached sender PID is checked
too (what NotifyAccess=main relies on).
"""

from __future__ import annotations

import os
import secrets
import socket
import struct
from collections.abc import Iterator
from pathlib import Path

import pytest

from gyrotherm._errors import ConfigError
from gyrotherm.daemon._sdnotify import Notifier

RECV_TIMEOUT_S = 5.0


class FakeClock:
    """Monotonic clock in ns that only moves when told to."""

    def __init__(self) -> None:
        self.now_ns = 1_000_000_000

    def __call__(self) -> int:
        return self.now_ns

    def advance(self, seconds: float) -> None:
        self.now_ns += round(seconds * 1e9)


def _bind_receiver(address: str) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_PASSCRED, 1)
    sock.bind(address)
    sock.settimeout(RECV_TIMEOUT_S)
    return sock


def _receive(sock: socket.socket) -> tuple[bytes, int]:
    """One datagram and the sender PID from SCM_CREDENTIALS."""
    data, ancdata, _flags, _addr = sock.recvmsg(4096, socket.CMSG_SPACE(12))
    pid = -1
    for level, kind, cmsg in ancdata:
        if level == socket.SOL_SOCKET and kind == socket.SCM_CREDENTIALS:
            pid, _uid, _gid = struct.unpack("=iII", cmsg[:12])
    return data, pid


def _assert_queue_empty(sock: socket.socket) -> None:
    # AF_UNIX datagrams are queued on the receiver before sendto() returns,
    # so an empty queue right after a call proves nothing was sent.
    sock.setblocking(False)
    try:
        with pytest.raises(BlockingIOError):
            sock.recv(4096)
    finally:
        sock.settimeout(RECV_TIMEOUT_S)


@pytest.fixture(params=["path", "abstract"])
def notify_endpoint(
    request: pytest.FixtureRequest, tmp_path: Path
) -> Iterator[tuple[str, socket.socket]]:
    """(NOTIFY_SOCKET value, bound receiving socket), path or abstract namespace."""
    if request.param == "path":
        path = str(tmp_path / "notify")
        sock = _bind_receiver(path)
        value = path
    else:
        name = f"gyrotherm-test-{os.getpid()}-{secrets.token_hex(6)}"
        sock = _bind_receiver("\0" + name)
        value = "@" + name
    try:
        yield value, sock
    finally:
        sock.close()


def test_messages_are_exact_datagrams_from_this_pid(
    notify_endpoint: tuple[str, socket.socket],
) -> None:
    value, receiver = notify_endpoint
    usec = iter([123_456_789])
    notifier = Notifier(value, monotonic_usec=lambda: next(usec))
    with notifier:
        assert notifier.enabled
        assert notifier.ready(status="bus can0 up, zenoh up")
        assert notifier.status("1 sensor\nOK\r")
        assert notifier.reloading()
        assert notifier.ready()
        assert notifier.stopping()
        assert notifier.extend_timeout(2.5)
        expected = [
            b"READY=1\nSTATUS=bus can0 up, zenoh up",
            b"STATUS=1 sensor OK",
            b"RELOADING=1\nMONOTONIC_USEC=123456789",
            b"READY=1",
            b"STOPPING=1",
            b"EXTEND_TIMEOUT_USEC=2500000",
        ]
        for want in expected:
            data, pid = _receive(receiver)
            assert data == want
            assert pid == os.getpid()
        _assert_queue_empty(receiver)
        assert notifier.sent == len(expected)
        assert notifier.send_failures == 0


def test_watchdog_sends_at_half_interval(notify_endpoint: tuple[str, socket.socket]) -> None:
    value, receiver = notify_endpoint
    clock = FakeClock()
    env = {"NOTIFY_SOCKET": value, "WATCHDOG_USEC": "5000000", "WATCHDOG_PID": "4242"}
    base = Notifier.from_environment(env, pid=4242)
    assert base.watchdog_interval_s == pytest.approx(5.0)
    notifier = Notifier(value, watchdog_interval_s=5.0, monotonic_ns=clock)
    with notifier:
        assert notifier.watchdog()  # first call always sends
        assert _receive(receiver)[0] == b"WATCHDOG=1"
        for _ in range(100):  # a busy loop at the same instant sends nothing more
            assert not notifier.watchdog()
        clock.advance(2.499_999)
        assert not notifier.watchdog()
        _assert_queue_empty(receiver)
        clock.advance(0.000_001)  # exactly half of 5 s since the last send
        assert notifier.watchdog()
        assert _receive(receiver)[0] == b"WATCHDOG=1"
        clock.advance(1.0)
        assert not notifier.watchdog()
        clock.advance(1.5)
        assert notifier.watchdog()
        assert _receive(receiver)[0] == b"WATCHDOG=1"
        _assert_queue_empty(receiver)
        assert notifier.sent == 3


def test_without_notify_socket_everything_is_a_no_op() -> None:
    notifier = Notifier.from_environment({"WATCHDOG_USEC": "5000000"})
    assert not notifier.enabled
    assert notifier.watchdog_interval_s is None
    assert not notifier.ready(status="x")
    assert not notifier.status("x")
    assert not notifier.watchdog()
    assert not notifier.reloading()
    assert not notifier.stopping()
    assert notifier.sent == 0
    assert notifier.send_failures == 0


def test_watchdog_pid_of_another_process_disarms_watchdog(tmp_path: Path) -> None:
    env = {
        "NOTIFY_SOCKET": str(tmp_path / "notify"),
        "WATCHDOG_USEC": "2000000",
        "WATCHDOG_PID": "1",
    }
    notifier = Notifier.from_environment(env, pid=2)
    assert notifier.enabled
    assert notifier.watchdog_interval_s is None
    assert not notifier.watchdog()
    # Without WATCHDOG_PID the watchdog is ours: 2 000 000 µs = 2 s.
    del env["WATCHDOG_PID"]
    assert Notifier.from_environment(env, pid=2).watchdog_interval_s == pytest.approx(2.0)


def test_send_failures_are_counted_not_raised(tmp_path: Path) -> None:
    clock = FakeClock()
    notifier = Notifier(
        str(tmp_path / "no-such-socket"), watchdog_interval_s=1.0, monotonic_ns=clock
    )
    with notifier:
        assert not notifier.ready()
        assert not notifier.watchdog()
        assert not notifier.watchdog()  # rate-limited: no second attempt yet
        clock.advance(0.5)
        assert not notifier.watchdog()
        assert notifier.send_failures == 3
        assert notifier.sent == 0
        assert notifier.last_error is not None
        assert "READY=1" not in notifier.last_error  # last failure was the watchdog
        assert "WATCHDOG=1" in notifier.last_error


@pytest.mark.parametrize(
    ("env", "fragment"),
    [
        ({"NOTIFY_SOCKET": "relative/path"}, "NOTIFY_SOCKET"),
        ({"NOTIFY_SOCKET": "vsock:2:1234"}, "NOTIFY_SOCKET"),
        ({"NOTIFY_SOCKET": "@"}, "NOTIFY_SOCKET"),
        ({"NOTIFY_SOCKET": "/run/x", "WATCHDOG_USEC": "soon"}, "WATCHDOG_USEC"),
        ({"NOTIFY_SOCKET": "/run/x", "WATCHDOG_USEC": "0"}, "WATCHDOG_USEC"),
        ({"NOTIFY_SOCKET": "/run/x", "WATCHDOG_USEC": "1", "WATCHDOG_PID": "me"}, "WATCHDOG_PID"),
    ],
)
def test_malformed_environment_names_the_variable(env: dict[str, str], fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment):
        Notifier.from_environment(env, pid=1)


def test_a_manager_that_stops_reading_cannot_stall_the_sender(tmp_path: Path) -> None:
    """Nobody reads the socket: once its queue is full each notification is dropped
    and counted after at most SEND_TIMEOUT_S (the processing loop sends them)."""
    import time

    from gyrotherm.daemon._sdnotify import SEND_TIMEOUT_S

    path = str(tmp_path / "notify")
    sock = _bind_receiver(path)  # bound, never read
    try:
        with Notifier(path) as notifier:
            sent_before_full = 0
            while notifier.status(f"fill {sent_before_full}"):  # until the queue is full
                sent_before_full += 1
                assert sent_before_full < 100_000
            t0 = time.monotonic()
            results = [notifier.status(f"late {i}") for i in range(20)]
            elapsed_s = time.monotonic() - t0
        assert not any(results)
        assert notifier.send_failures == 21 and notifier.sent == sent_before_full
        assert elapsed_s < 20 * 1.0  # the old 1 s wait per send would take ≥ 20 s
        assert SEND_TIMEOUT_S <= 0.05
    finally:
        sock.close()
