"""Read and write CAN logs in the ``candump -l`` format of Linux can-utils.

One frame per line::

    (1700000000.123456) can0 120#F4011EFBFF7F001A

* ``(seconds.microseconds)``: the timestamp (``time_s`` of decoded samples);
* the interface name (kept as ``can.Message.channel``);
* the frame: ``<id>#<data>``. ``<id>`` is 3 hex digits for a standard (11-bit)
  id, 8 for an extended (29-bit) one; 8 digits with bit 0x20000000 set is an
  error frame (the remaining bits are its error class). ``<data>`` is 0–8
  bytes as hex pairs (``.`` separators allowed). ``<id>#R`` or ``<id>#R<dlc>``
  is a remote frame. ``<id>##<flags><data>`` is CAN FD, ``<flags>`` one hex
  digit (0x1 bit-rate switch, 0x2 error state indicator), 0–64 data bytes of a
  valid FD length. A classic 8-byte frame's ``_<dlc>`` suffix (raw DLC 9..F)
  is accepted and ignored. A trailing `` R`` / `` T`` (rx/tx, as python-can
  writes) is accepted and ignored.

Blank lines are skipped. A malformed line raises :class:`gyrotherm.DecodeError`
naming file, line number and problem. The writer emits exactly the
``candump -l`` form (timestamp ``%010d.%06d``, uppercase hex, no direction).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Iterator
from pathlib import Path

import can

from gyrotherm._errors import DecodeError

CAN_ERR_FLAG = 0x20000000
_FD_LENGTHS = frozenset((*range(9), 12, 16, 20, 24, 32, 48, 64))
_LINE = re.compile(
    r"^\((?P<ts>\d+\.\d+)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]+)#(?P<rest>\S*)(?:\s+[RTrt])?$"
)


def _hex_bytes(text: str, what: str) -> bytes:
    digits = text.replace(".", "")
    if len(digits) % 2:
        raise ValueError(f"{what} has an odd number of hex digits: {text!r}")
    try:
        return bytes.fromhex(digits)
    except ValueError:
        raise ValueError(f"{what} is not hex: {text!r}") from None


def _parse(line: str) -> can.Message:
    m = _LINE.match(line.strip())
    if m is None:
        raise ValueError("expected '(<seconds>.<fraction>) <interface> <id>#<data>'")
    ident, rest = m["id"], m["rest"]
    if len(ident) not in (3, 8):
        raise ValueError(f"CAN id {ident!r} must have 3 (standard) or 8 (extended) hex digits")
    can_id = int(ident, 16)
    extended = len(ident) == 8
    error = extended and bool(can_id & CAN_ERR_FLAG)
    if extended and not error and can_id > 0x1FFFFFFF:
        raise ValueError(f"extended CAN id 0x{can_id:08X} exceeds 0x1FFFFFFF")
    if not extended and can_id > 0x7FF:
        raise ValueError(f"standard CAN id 0x{can_id:03X} exceeds 0x7FF")
    fd = rest.startswith("#")
    remote = not fd and rest[:1] in ("R", "r")
    brs = esi = False
    dlc: int | None = None
    data = b""
    if fd:
        if len(rest) < 2 or rest[1] not in "0123456789ABCDEFabcdef":
            raise ValueError("CAN FD frame needs a flags hex digit after '##'")
        flags = int(rest[1], 16)
        brs, esi = bool(flags & 0x1), bool(flags & 0x2)
        data = _hex_bytes(rest[2:], "CAN FD data")
        if len(data) not in _FD_LENGTHS:
            raise ValueError(f"CAN FD data length {len(data)} is not a valid FD length")
    elif remote:
        tail = rest[1:].split("_", 1)[0]
        if tail and not (tail.isdigit() and int(tail) <= 8):
            raise ValueError(f"remote frame length {tail!r} is not 0..8")
        dlc = int(tail) if tail else 0
    else:
        payload, _, raw_dlc = rest.partition("_")
        data = _hex_bytes(payload, "data")
        if len(data) > 8:
            raise ValueError(f"classic CAN data has {len(data)} bytes, at most 8 allowed")
        if raw_dlc and not (len(data) == 8 and re.fullmatch(r"[9A-Fa-f]", raw_dlc)):
            raise ValueError(f"raw DLC suffix '_{raw_dlc}' needs 8 data bytes and a digit 9..F")
    return can.Message(
        timestamp=float(m["ts"]),
        channel=m["ch"],
        arbitration_id=can_id & 0x1FFFFFFF,
        is_extended_id=extended and not error,
        is_error_frame=error,
        is_remote_frame=remote,
        is_fd=fd,
        bitrate_switch=brs,
        error_state_indicator=esi,
        dlc=dlc,
        data=data,
        check=True,
    )


def parse_candump_line(line: str, *, source: str = "<string>", line_no: int = 1) -> can.Message:
    """One ``candump -l`` line → ``can.Message``; DecodeError names ``source:line_no``."""
    try:
        return _parse(line)
    except ValueError as exc:
        raise DecodeError(f"{source}:{line_no}: {exc}: {line.rstrip()!r}") from exc


def iter_candump(lines: Iterable[str], *, source: str = "<string>") -> Iterator[can.Message]:
    """Messages of ``candump -l`` lines (blank lines skipped), in order."""
    for line_no, line in enumerate(lines, start=1):
        if line.strip():
            yield parse_candump_line(line, source=source, line_no=line_no)


def read_candump(path: str | os.PathLike[str]) -> Iterator[can.Message]:
    """Messages of a ``candump -l`` log file, lazily, in file order."""
    p = Path(path)
    try:
        f = p.open(encoding="utf-8", errors="strict")
    except OSError as exc:
        raise DecodeError(f"{p}: cannot open candump log: {exc}") from exc
    with f:
        try:
            yield from iter_candump(f, source=str(p))
        except UnicodeDecodeError as exc:
            raise DecodeError(f"{p}: not a text candump log: {exc}") from exc


def format_candump_line(msg: can.Message, *, channel: str = "can0") -> str:
    """One ``candump -l`` line (no newline); ``channel`` is used when ``msg`` has none.

    Raises :class:`gyrotherm.DecodeError` for a message that cannot be written
    (negative timestamp, id out of range, more than 8 bytes in a classic frame).
    """
    ts_us = round(float(msg.timestamp) * 1_000_000)
    if ts_us < 0:
        raise DecodeError(f"cannot write frame 0x{msg.arbitration_id:X}: timestamp "
                          f"{msg.timestamp} is negative")
    sec, usec = divmod(ts_us, 1_000_000)
    ch = msg.channel
    name = f"can{ch}" if isinstance(ch, int) else (ch if isinstance(ch, str) and ch else channel)
    limit = 0x1FFFFFFF if msg.is_extended_id or msg.is_error_frame else 0x7FF
    if not 0 <= msg.arbitration_id <= limit:
        raise DecodeError(f"cannot write frame: id 0x{msg.arbitration_id:X} exceeds 0x{limit:X}")
    if msg.is_error_frame:
        ident = f"{CAN_ERR_FLAG | msg.arbitration_id:08X}"
    elif msg.is_extended_id:
        ident = f"{msg.arbitration_id:08X}"
    else:
        ident = f"{msg.arbitration_id:03X}"
    data = bytes(msg.data or b"")
    if msg.is_fd:
        flags = (0x1 if msg.bitrate_switch else 0) | (0x2 if msg.error_state_indicator else 0)
        frame = f"#{flags:X}{data.hex().upper()}"
    elif msg.is_remote_frame:
        frame = f"R{msg.dlc}" if msg.dlc else "R"
    else:
        if len(data) > 8:
            raise DecodeError(f"cannot write frame 0x{msg.arbitration_id:X}: classic CAN "
                              f"frame has {len(data)} bytes, at most 8 allowed")
        frame = data.hex().upper()
    return f"({sec:010d}.{usec:06d}) {name} {ident}#{frame}"


def write_candump(
    path: str | os.PathLike[str], messages: Iterable[can.Message], *, channel: str = "can0"
) -> int:
    """Write ``messages`` as a ``candump -l`` log (overwrites); returns the frame count."""
    n = 0
    with Path(path).open("w", encoding="utf-8", newline="\n") as f:
        for msg in messages:
            f.write(format_candump_line(msg, channel=channel) + "\n")
            n += 1
    return n
