"""Fuzz of the socketcand reader (hypothesis, derandomised, bounded examples).

Independent truth: a regular expression tokenises the whole stream at once —
``<[^<>]*>`` a complete item, ``<[^<>]*`` an item cut off by the next ``<`` or
by the end, ``[^<]+`` bytes outside items (counted when not only whitespace) —
and every valid frame line is built from known field values. The reader sees
the same bytes cut into random chunks (or through TCP) and must return exactly
one result per token, in order, with every untouched frame line decoded to its
values.
"""

from __future__ import annotations

import re
import sys
import time
from itertools import pairwise
from pathlib import Path

import can
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrotherm.bus import TRANSPORT_MALFORMED, SocketcandBus, TransportItem
from gyrotherm.bus._socketcand_items import ItemSplitter, Result

sys.path.insert(0, str(Path(__file__).resolve().parent))
from socketcandkit import WAIT_S, HostilePeer

TOKEN = re.compile(rb"<[^<>]*>|<[^<>]*|[^<]+")
Truth = tuple[int, bool, bytes, float]


def tokens(stream: bytes) -> list[bytes]:
    """The items the reader must report, in order (outside whitespace is not one)."""
    return [t for t in TOKEN.findall(stream) if t.startswith(b"<") or t.strip()]


@st.composite
def frame_lines(draw: st.DrawFn) -> tuple[bytes, Truth]:
    extended = draw(st.booleans())
    arb = draw(st.integers(0, 0x1FFFFFFF if extended else 0x7FF))
    data = draw(st.binary(max_size=8))
    sec, usec = draw(st.integers(0, 4_000_000_000)), draw(st.integers(0, 999_999))
    ident = f"{arb:08X}" if extended else f"{arb:03X}"
    line = f"< frame {ident} {sec}.{usec:06d} {data.hex().upper()} >".encode()
    return line, (arb, extended, data, float(f"{sec}.{usec:06d}"))


@st.composite
def mutated(draw: st.DrawFn) -> tuple[bytes, dict[bytes, Truth]]:
    """Valid frame lines, some mutated (bytes inserted, deleted, replaced), and noise."""
    parts: list[bytes] = []
    truth: dict[bytes, Truth] = {}
    for _ in range(draw(st.integers(0, 12))):
        kind = draw(st.sampled_from(["frame", "frame", "mutate", "noise"]))
        if kind == "noise":
            parts.append(draw(st.binary(max_size=40)))
            continue
        line, t = draw(frame_lines())
        if kind == "mutate":
            i = draw(st.integers(0, len(line) - 1))
            op = draw(st.sampled_from(["insert", "delete", "replace"]))
            b = draw(st.binary(min_size=1, max_size=3))
            line = (line[:i] + b + line[i:] if op == "insert" else
                    line[:i] + line[i + 1:] if op == "delete" else line[:i] + b + line[i + 1:])
        else:
            truth[line] = t
        parts.append(line)
    return b"".join(parts), truth


def fields(r: Result) -> object:
    if isinstance(r, can.Message):
        return (r.arbitration_id, r.is_extended_id, bytes(r.data), r.timestamp)
    return r.reason


def check(stream: bytes, truth: dict[bytes, Truth], results: list[Result]) -> None:
    expected = tokens(stream)
    assert len(results) == len(expected), (stream, expected, results)
    for tok, r in zip(expected, results, strict=True):
        assert isinstance(r, can.Message | TransportItem)
        if tok in truth:
            assert fields(r) == truth[tok], (tok, r)
        elif not (tok.startswith(b"<") and tok.endswith(b">")):
            assert fields(r) == TRANSPORT_MALFORMED, (tok, r)  # outside or cut off


def split(stream: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(stream) + 1) for c in cuts} | {0, len(stream)})
    return [stream[a:b] for a, b in pairwise(points)]


def through_splitter(chunks: list[bytes]) -> list[Result]:
    splitter, out = ItemSplitter("vcan0"), []
    for chunk in chunks:
        splitter.feed(chunk, out)
    splitter.close(out)
    return out


@settings(derandomize=True, max_examples=400, deadline=None)
@given(mutated(), st.lists(st.integers(0, 10_000), max_size=20))
def test_mutated_frames_in_random_chunks(case: tuple[bytes, dict[bytes, Truth]],
                                         cuts: list[int]) -> None:
    stream, truth = case
    check(stream, truth, through_splitter(split(stream, cuts)))


@settings(derandomize=True, max_examples=400, deadline=None)
@given(st.binary(max_size=300), st.lists(st.integers(0, 10_000), max_size=20))
def test_random_bytes_in_random_chunks(stream: bytes, cuts: list[int]) -> None:
    check(stream, {}, through_splitter(split(stream, cuts)))


@settings(derandomize=True, max_examples=25, deadline=None)
@given(mutated(), st.lists(st.integers(0, 10_000), max_size=8))
def test_mutated_frames_through_tcp(case: tuple[bytes, dict[bytes, Truth]],
                                    cuts: list[int]) -> None:
    """The same oracle end to end: hostile peer → TCP → SocketcandBus.recv until EOF."""
    stream, truth = case
    with HostilePeer(split(stream, cuts) if stream else []) as peer:
        with SocketcandBus.connect("127.0.0.1", peer.port, "vcan0") as bus:
            assert peer.sent.wait(WAIT_S)
            peer.vanish()
            results: list[Result] = []
            deadline = time.monotonic() + WAIT_S
            while ((r := bus.recv(0.05)) is not None or not bus.link_lost) \
                    and time.monotonic() < deadline:
                if r is not None:
                    results.append(r)
            assert bus.link_lost
    check(stream, truth, results)
