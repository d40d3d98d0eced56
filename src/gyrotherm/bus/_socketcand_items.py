"""Split a socketcand byte stream into frames and transport items; never raises.

:class:`ItemSplitter` is the pure (socket-free) half of
:class:`~gyrotherm.bus._socketcand.SocketcandBus`: :meth:`ItemSplitter.feed`
takes TCP chunks as they come (an item may be split anywhere) and appends one
result per item to a list; :meth:`ItemSplitter.close` ends the stream.

Items (after the handshake; every ``<`` starts one):

* ``< frame ID SEC.USEC DATA >`` exactly as socketcand prints it (single spaces;
  ``ID`` 3 hex digits: 11-bit id ≤ 0x7FF, 8 hex digits: 29-bit id ≤ 0x1FFFFFFF;
  ``SEC.USEC`` ASCII digits with one dot; ``DATA`` 0–16 hex digits, even, empty
  for a frame without data, which still has both spaces: ``< frame 123 1.000000  >``)
  → a :class:`can.Message`, as python-can's client builds it: ``timestamp`` the
  sender's ``float(SEC.USEC)``, ``is_extended_id`` for an 8-digit id, ``dlc`` =
  data length, ``is_rx``, ``channel``. Upper- or lower-case hex.
* :data:`TRANSPORT_MALFORMED` — a frame item that breaks any rule above; an item
  with bytes outside printable ASCII (NUL, UTF-8, control characters) or with
  nothing inside; an item cut off by the next ``<`` (truncated) or by the end
  of the stream; an item longer than :data:`MAX_ITEM_BYTES` (its bytes are
  discarded up to the next ``<``, so the buffer stays bounded); and each run of
  non-whitespace bytes outside ``< >`` (one item per run, however long).
* :data:`TRANSPORT_ERROR` — ``< error … >``: the server's error lines
  (``< error unknown command >``) and socketcand's CAN error-frame report.
* :data:`TRANSPORT_OTHER` — any other well-formed item (``< ok >``,
  ``< echo >``, ``< fdframe … >``, BCM replies).

Whitespace between items is ignored. A good frame before or after a bad item is
delivered unchanged: the splitter resynchronises at the next ``<``.
"""

from __future__ import annotations

from binascii import a2b_hex

import can

from gyrotherm.bus._bus import TransportItem

TRANSPORT_MALFORMED = "transport_malformed"
"""Drop reason: bytes that are not a well-formed socketcand item (see module docstring)."""
TRANSPORT_ERROR = "transport_error"
"""Drop reason: a ``< error … >`` line from the server."""
TRANSPORT_OTHER = "transport_other"
"""Drop reason: a well-formed item that is not a frame (``< ok >``, ``< echo >``, …)."""
REASONS = (TRANSPORT_MALFORMED, TRANSPORT_ERROR, TRANSPORT_OTHER)
MAX_ITEM_BYTES = 4096
"""Longest item kept, ``<`` and ``>`` included; longer ones are malformed and discarded."""

_HEX = b"0123456789abcdefABCDEF"
_SLOTS = {"timestamp", "arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame",
          "channel", "is_fd", "is_rx", "bitrate_switch", "error_state_indicator", "data", "dlc"}
_DIRECT = set(getattr(can.Message, "__slots__", ())) - {"__weakref__"} == _SLOTS
"""can.Message has exactly these slots (python-can 4.x): set them without ``__init__``."""
_new = object.__new__
_Message = can.Message
_PRINTABLE = bytes(range(0x20, 0x7F))
_QUOTE_BYTES = 64

Result = can.Message | TransportItem


def quote(raw: bytes) -> str:
    """``raw`` for a log line: repr of at most 64 bytes, with the full length if cut."""
    if len(raw) <= _QUOTE_BYTES:
        return repr(raw)
    return f"{raw[:_QUOTE_BYTES]!r}… ({len(raw)} bytes)"


def _malformed(why: str, raw: bytes) -> TransportItem:
    return TransportItem(TRANSPORT_MALFORMED, f"{why}: {quote(raw)}")


def parse_frame(ident: bytes, ts: bytes, hexdata: bytes, channel: str) -> can.Message | str:
    """The frame of a ``< frame ID SEC.USEC DATA >`` item's fields, or why it is malformed."""
    n = len(ident)
    if n != 3 and n != 8:
        return f"id {ident!r} must have 3 (11-bit) or 8 (29-bit) hex digits"
    if ident.translate(None, _HEX):
        return f"id {ident!r} is not hexadecimal"
    arb = int(ident, 16)
    if n == 3 and arb > 0x7FF:
        return f"11-bit id {ident!r} above 0x7FF"
    if arb > 0x1FFFFFFF:
        return f"29-bit id {ident!r} above 0x1FFFFFFF"
    sec, dot, frac = ts.partition(b".")
    if not (dot and sec.isdigit() and frac.isdigit()):
        return f"time stamp {ts!r} is not SEC.USEC in decimal digits"
    if len(hexdata) > 16:
        return f"data {hexdata!r} longer than 8 bytes"
    try:
        data = bytearray(a2b_hex(hexdata))
    except ValueError:
        return f"data {hexdata!r} is not an even number of hex digits"
    if not _DIRECT:  # another python-can: its own constructor
        return can.Message(timestamp=float(ts), arbitration_id=arb, is_extended_id=n == 8,
                           channel=channel, dlc=len(data), data=data, is_rx=True, check=False)
    # what can.Message(..., check=False) sets, in a third of its time (hot path)
    msg = _new(_Message)
    msg.timestamp = float(ts)
    msg.arbitration_id = arb
    msg.is_extended_id = n == 8
    msg.is_remote_frame = msg.is_error_frame = msg.is_fd = False
    msg.bitrate_switch = msg.error_state_indicator = False
    msg.is_rx = True
    msg.channel = channel
    msg.data = data
    msg.dlc = len(data)
    return msg


def classify(item: bytes, channel: str) -> Result:
    """One complete item ``<…>`` (brackets included) as a frame or a transport item."""
    if len(item) > MAX_ITEM_BYTES:
        return _malformed(f"item longer than {MAX_ITEM_BYTES} bytes", item)
    body = item[1:-1]
    if body.translate(None, _PRINTABLE):
        return _malformed("item with bytes outside printable ASCII", item)
    words = body.split()
    if not words:
        return _malformed("empty item", item)
    if words[0] == b"frame":
        f = body.split(b" ")
        if len(f) != 6 or f[0] or f[1] != b"frame" or f[5]:
            return _malformed("frame is not '< frame ID SEC.USEC DATA >'", item)
        msg = parse_frame(f[2], f[3], f[4], channel)
        return msg if isinstance(msg, can.Message) else _malformed(msg, item)
    if words[0] == b"error":
        return TransportItem(TRANSPORT_ERROR, f"server error: {quote(item)}")
    return TransportItem(TRANSPORT_OTHER, f"not a frame: {quote(item)}")


class ItemSplitter:
    """Incremental splitter of one connection's stream (not thread-safe).

    Memory is bounded: at most one pending item of :data:`MAX_ITEM_BYTES` is kept
    between calls.
    """

    def __init__(self, channel: str) -> None:
        self.channel = channel
        self._tail = b""  # a pending item: starts with "<", no ">" yet
        self._skip = False  # inside a discarded over-long item: ignore up to the next "<"
        self._outside_seen = False  # the current run of bytes outside < > was reported

    def _outside(self, raw: bytes, out: list[Result]) -> None:
        if not self._skip and not self._outside_seen and raw.strip():
            self._outside_seen = True
            out.append(_malformed("bytes outside '< >'", raw.strip()))

    def _item(self, piece: bytes, out: list[Result]) -> None:
        """``piece``: the bytes after one ``<`` up to the next ``<`` (exclusive)."""
        self._skip = self._outside_seen = False
        end = piece.find(b">")
        if end < 0:
            out.append(_malformed("item cut off by the next '<'", b"<" + piece))
            return
        out.append(classify(b"<" + piece[: end + 1], self.channel))
        if end + 1 < len(piece):
            self._outside(piece[end + 1 :], out)

    def feed(self, chunk: bytes, out: list[Result]) -> None:
        """Append the result of every item ``chunk`` completes to ``out``."""
        pieces = (self._tail + chunk if self._tail else chunk).split(b"<")
        if self._tail:
            self._tail = b""
        elif pieces[0]:
            self._outside(pieces[0], out)
        last = len(pieces) - 1
        if last == 0:
            return
        channel = self.channel
        for i in range(1, last):
            piece = pieces[i]
            f = piece.split(b" ")
            # fast path: b" frame ID SEC.USEC DATA >" with nothing after ">"
            if len(f) == 6 and f[5] == b">" and f[1] == b"frame" and not f[0]:
                msg = parse_frame(f[2], f[3], f[4], channel)
                if type(msg) is can.Message:  # (the state flags matter only after the
                    out.append(msg)  # last piece, which always takes the slow path)
                    continue
            self._item(piece, out)
        piece = pieces[last]
        if b">" in piece:
            self._item(piece, out)
        elif len(piece) < MAX_ITEM_BYTES:
            self._skip = self._outside_seen = False
            self._tail = b"<" + piece
        else:
            out.append(_malformed(f"item longer than {MAX_ITEM_BYTES} bytes", b"<" + piece))
            self._skip = True

    def close(self, out: list[Result]) -> None:
        """The stream ended: a pending partial item becomes one malformed item."""
        if self._tail:
            out.append(_malformed("item cut off by the end of the stream", self._tail))
            self._tail = b""
