"""A hostile socketcand peer cannot end a real ``gyrotherm run`` process.

The testers' malformed cases (a non-hex id, a time stamp that is not a number,
non-hex or odd-length data, a frame without its data field, a truncated frame
followed by a good one, non-ASCII and NUL bytes, ``< error unknown command >`` …)
are sent many times between valid gyro frames, split across TCP writes at
random (seeded). Independent truth: what was sent. The daemon must stay up,
count every item exactly under its reason (frames in = published + Σ drops),
log each reason only 1, 2, 4, 8 … times, and stop cleanly on SIGTERM.
"""

from __future__ import annotations

import math
import random
import sys
from collections import Counter
from pathlib import Path

from gyrotherm.bus import TRANSPORT_ERROR, TRANSPORT_MALFORMED, TRANSPORT_OTHER
from gyrotherm.client import Subscriber
from gyrotherm.codecs import FrameEncoder, RateSample, TemperatureSample
from gyrotherm.sim._socketcand_wire import encode_frame
from streamkit import free_port

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bus"))
from faultkit import WAIT_S, DaemonProc, write_config
from socketcandkit import HostilePeer

ROUNDS = 40
BAD: dict[str, tuple[bytes, str]] = {
    "non-hex id": (b"< frame ZZZ 1.000000 F4011EFB96000528 >", TRANSPORT_MALFORMED),
    "time stamp not a number": (b"< frame 120 17x0.00abc 0102 >", TRANSPORT_MALFORMED),
    "non-hex data": (b"< frame 120 1.000000 01G2 >", TRANSPORT_MALFORMED),
    "odd-length data": (b"< frame 120 1.000000 012 >", TRANSPORT_MALFORMED),
    "no data field": (b"< frame 120 1.000000 >", TRANSPORT_MALFORMED),
    "truncated frame": (b"< frame 120 1700000000.0000", TRANSPORT_MALFORMED),
    "non-ASCII": (b"< frame 120 1.000000 0102\xc3\xa9\xff >", TRANSPORT_MALFORMED),
    "NUL": (b"< frame 120\x00 1.000000 01 >", TRANSPORT_MALFORMED),
    "oversized item": (b"< frame " + b"A" * 5000 + b" >", TRANSPORT_MALFORMED),
    "bytes outside < >": (b"garbage\xff", TRANSPORT_MALFORMED),
    "server error line": (b"< error unknown command >", TRANSPORT_ERROR),
    "ok after handshake": (b"< ok >", TRANSPORT_OTHER),
}


def _stream(seed: int) -> tuple[list[bytes], int, Counter[str]]:
    """Chunks of the byte stream, the number of valid frames, the expected drops."""
    rnd = random.Random(seed)
    enc = FrameEncoder()
    parts: list[bytes] = []
    expected: Counter[str] = Counter()
    valid = 0
    t0 = 1_700_000_000.0
    for r in range(ROUNDS):
        for case in rnd.sample(list(BAD), len(BAD)):  # every case, in a random order
            t = t0 + 0.01 * valid
            if valid % 10 == 0:
                frame = enc.encode_temperature(TemperatureSample(t, 25.0 + 0.001 * r))
            else:
                frame = enc.encode_rate(RateSample(t, 0.1, -0.2, 0.3))
            parts += [encode_frame(frame), BAD[case][0]]
            valid += 1
            expected[BAD[case][1]] += 1
    blob = b"".join(parts) + encode_frame(enc.encode_rate(RateSample(t0 + 0.01 * valid, 0, 0, 0)))
    valid += 1
    cuts = sorted(rnd.sample(range(1, len(blob)), 300))
    chunks = [blob[a:b] for a, b in zip([0, *cuts], [*cuts, len(blob)], strict=True)]
    return chunks, valid, expected


def test_malformed_socketcand_text_never_ends_the_daemon(tmp_path: Path) -> None:
    chunks, valid, expected = _stream(seed=11)
    total = valid + sum(expected.values())
    zenoh_port = free_port()
    latest: dict[str, int] = {}
    with HostilePeer(chunks) as peer:
        config = write_config(tmp_path / "g.toml", bus_port=peer.port, zenoh_port=zenoh_port,
                              extra_can="reopen_after_s = 3600")
        daemon = DaemonProc(config)
        try:
            with Subscriber("faults", "imu0", connect=[f"tcp/127.0.0.1:{zenoh_port}"],
                            on_health=lambda h: latest.__setitem__("in", h.frames_received)
                            ) as sub:
                assert peer.sent.wait(WAIT_S), daemon.err.text()
                counted = sub.wait_for(lambda _s: latest.get("in", 0) >= total, timeout_s=WAIT_S)
                assert counted, (latest, total, daemon.err.lines[-5:])
            assert daemon.proc.poll() is None, daemon.err.text()  # still up after all of it
            assert daemon.terminate() < WAIT_S
        finally:
            daemon.kill()
    assert daemon.proc.returncode == 0, daemon.err.text()
    frames_in, published, drops = daemon.summary()
    assert frames_in == total
    assert published + sum(drops.values()) == frames_in
    # every valid frame published, or sent to nobody before the subscriber matched
    assert published + drops.pop("no_subscriber", 0) == valid
    assert drops == dict(expected)
    # rate-limited: each reason logged on its 1st, 2nd, 4th, 8th … occurrence only
    for reason, n in expected.items():
        lines = [x for x in daemon.err.lines if reason in x and "WARNING" in x]
        assert 1 <= len(lines) <= math.floor(math.log2(n)) + 1, (reason, n, lines)
    assert not any("Traceback" in x for x in daemon.err.lines), daemon.err.text()
