"""The socketcand ASCII protocol as text: frame lines, ``< send >`` commands, demo frames.

:class:`~gyrotherm.sim._socketcand.SocketcandServer` serves the ASCII protocol
of socketcand (github.com/linux-can/socketcand, ``doc/protocol.md`` and
``state_raw.c``) and the daemon reads it with gyrotherm's own client,
:class:`gyrotherm.bus.SocketcandBus` (python-can's
``can.Bus(interface="socketcand", ...)`` works too).

Session, as python-can's client drives it (every reply is its own TCP write)::

    server: < hi >
    client: < open vcan0 >     server: < ok >       (other channel: error, close)
    client: < rawmode >        server: < ok >
    server: < frame 123 1700000000.000042 0102AB >          (11-bit id: 3 hex digits)
    server: < frame 1ABCDEF0 1700000000.000043  >           (29-bit id: 8 digits, no data)
    client: < send 123 3 1 2 ab >                           (8 id digits: extended)

``< frame ID SEC.USEC DATA >`` carries the message's own ``timestamp`` (seconds,
rounded to the microsecond) and the data as contiguous upper-case hex, exactly
as socketcand prints it. ``< echo >`` is answered with ``< echo >``,
``< bcmmode >`` stops the stream; any other command gets
``< error unknown command >``. Classic CAN only (0–8 data bytes, standard and
extended ids); CAN FD, remote and error frames are rejected with
:class:`gyrotherm.DecodeError`.

:func:`_peer_unread_bytes` reads ``/proc/net/tcp`` for the handshake settle
check of :mod:`gyrotherm.sim._socketcand_client`.
"""

from __future__ import annotations

import math

import can

from gyrotherm._errors import DecodeError


def _reject(msg: can.Message, why: str) -> DecodeError:
    return DecodeError(f"frame 0x{msg.arbitration_id:X}: cannot be sent over socketcand: {why}")


def encode_frame(msg: can.Message) -> bytes:
    """The ``< frame ID SEC.USEC DATA >`` line for a classic CAN frame."""
    arb, data = msg.arbitration_id, msg.data
    if msg.is_fd or msg.is_remote_frame or msg.is_error_frame:
        raise _reject(msg, "only classic data frames are supported (no FD, remote, error)")
    if len(data) > 8 or msg.dlc != len(data):
        raise _reject(msg, f"dlc {msg.dlc} with {len(data)} data bytes, limit 0..8 and equal")
    if msg.is_extended_id:
        if not 0 <= arb <= 0x1FFFFFFF:
            raise _reject(msg, "extended id outside 0..0x1FFFFFFF")
        ident = f"{arb:08X}"
    else:
        if not 0 <= arb <= 0x7FF:
            raise _reject(msg, "standard id outside 0..0x7FF")
        ident = f"{arb:03X}"
    ts = msg.timestamp
    if not (ts >= 0.0 and math.isfinite(ts)):
        raise _reject(msg, f"timestamp {ts!r} s, must be finite and >= 0")
    sec, usec = divmod(round(ts * 1_000_000), 1_000_000)
    return f"< frame {ident} {sec}.{usec:06d} {data.hex().upper()} >".encode("ascii")


def parse_send(command: str, *, channel: str, timestamp_s: float) -> can.Message:
    """Decode ``< send ID DLC B0 B1 ... >`` (hex fields; 8 id digits: extended id)."""
    words = command.strip("<> \t\r\n").split()
    try:
        if len(words) < 3 or words[0] != "send":
            raise ValueError("expected '< send can_id can_dlc [data]* >'")
        ident, dlc, payload = words[1], int(words[2], 16), words[3:]
        extended = len(ident) == 8
        arb = int(ident, 16)
        if arb > (0x1FFFFFFF if extended else 0x7FF) or arb < 0:
            raise ValueError(
                f"id {ident} out of range for {'extended' if extended else 'standard'}"
            )
        if not 0 <= dlc <= 8 or len(payload) != dlc:
            raise ValueError(f"dlc {dlc} with {len(payload)} data bytes, limit 0..8 and equal")
        data = bytes(int(b, 16) for b in payload)
    except ValueError as exc:
        raise DecodeError(f"socketcand command {command!r}: {exc}") from exc
    return can.Message(
        timestamp=timestamp_s,
        arbitration_id=arb,
        is_extended_id=extended,
        data=data,
        is_rx=True,
        channel=channel,
    )


def demo_frame(index: int) -> can.Message:
    """Deterministic test frame ``index`` (what ``--frames N`` plays).

    Odd ``index``: extended id ``0x1ABC0000 + index``; even: standard id
    ``index % 0x800``. Data: ``index % 9`` bytes ``(index + k) % 256``. Timestamp:
    ``1_700_000_000 s + index ms + (index % 1000) µs``.
    """
    extended = index % 2 == 1
    arb = (0x1ABC0000 + index) & 0x1FFFFFFF if extended else index % 0x800
    data = bytes((index + k) % 256 for k in range(index % 9))
    ts_us = 1_700_000_000_000_000 + 1_000 * index + index % 1_000
    return can.Message(
        timestamp=ts_us / 1e6, arbitration_id=arb, is_extended_id=extended, data=data
    )


def _peer_unread_bytes(server_port: int, client_port: int) -> int | None:
    """Bytes the server sent that the local peer has not read yet, or None if unknown."""
    ours = theirs = None
    for path in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            with open(path, encoding="ascii") as table:
                rows = table.read().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            f = row.split()
            if len(f) < 5 or f[3] != "01":  # 01: ESTABLISHED
                continue
            local, remote = int(f[1].rsplit(":", 1)[1], 16), int(f[2].rsplit(":", 1)[1], 16)
            tx_queue, rx_queue = (int(q, 16) for q in f[4].split(":"))
            if (local, remote) == (server_port, client_port):
                ours = tx_queue  # sent but not yet acknowledged by the peer's kernel
            elif (local, remote) == (client_port, server_port):
                theirs = rx_queue  # received by the peer's kernel, not yet read
    if theirs is None:
        return None
    return theirs + (ours or 0)
