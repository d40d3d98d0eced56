"""Subscriber through real zenoh sessions on 127.0.0.1: typed samples, gaps, latency, errors."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import msgpack
import pytest
import zenoh

from gyrotherm import CalibrationError, ConfigError
from gyrotherm._zenoh import KeyExprs, keys, open_session, session_config
from gyrotherm.client import (
    LatencyTracker,
    SequenceTracker,
    Subscriber,
    listen_main,
    percentile,
)
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    RateMessage,
    StateMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
    encode_rate,
    encode_state,
)
from streamkit import dead_port, open_ephemeral

VEHICLE, SENSOR = "testcar", "imu0"
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "servo_loop.py"
WAIT_S = 15.0  # generous bound for 2 shared cores; never reached when things work


def rate(seq: int, *, receive_time_s: float | None = None, z_dps: float = 0.5) -> RateMessage:
    t = time.time() if receive_time_s is None else receive_time_s
    return RateMessage(seq, seq * 0.0005, t, (0.1, -0.2, z_dps), (0.15, -0.1, z_dps + 0.25),
                       (0.05, 0.1, 0.25), StatusFlags.NONE)  # fmt: skip


@dataclass
class Daemon:
    """A stand-in publisher: a zenoh session listening on a kernel-chosen loopback port."""

    endpoint: str
    session: zenoh.Session
    keys: KeyExprs

    def publisher(self, key: str) -> zenoh.Publisher:
        return self.session.declare_publisher(key)

    def wait_matched(self, pub: zenoh.Publisher, timeout_s: float = WAIT_S) -> None:
        """Wait (bounded) until a remote subscriber matches ``pub``."""
        matched = threading.Event()
        listener = pub.declare_matching_listener(lambda s: s.matching and matched.set())
        try:
            if pub.matching_status.matching:
                matched.set()
            assert matched.wait(timeout_s), f"no subscriber matched {pub.key_expr}"
        finally:
            listener.undeclare()


@pytest.fixture
def daemon() -> Iterator[Daemon]:
    session, endpoint = open_ephemeral(session_config(listen=["tcp/127.0.0.1:0"]))
    with session:
        yield Daemon(endpoint, session, keys(VEHICLE, SENSOR))


# ----------------------------------------------------------------- pure logic
@pytest.mark.parametrize(
    ("seqs", "gaps", "missing", "resets", "dups"),
    [
        ([0, 1, 2, 3], 0, 0, 0, 0),
        ([0, 1, 2, 5, 6], 1, 2, 0, 0),
        ([7, 8, 12, 20], 2, 10, 0, 0),  # joining late at 7 is not a gap
        ([0, 1, 2, 0, 1], 0, 0, 1, 0),  # publisher restart
        ([0, 1, 2, 3, 2], 1, 2, 1, 0),  # restart first seen at seq 2: 0 and 1 of it lost
        ([0, 1, 1, 2], 0, 0, 0, 1),
    ],
)
def test_sequence_tracker(seqs: list[int], gaps: int, missing: int, resets: int,
                          dups: int) -> None:  # fmt: skip
    t = SequenceTracker()
    for s in seqs:
        t.observe(s)
    assert (t.gaps, t.missing, t.resets, t.duplicates) == (gaps, missing, resets, dups)
    assert t.last_seq == seqs[-1]


def test_latency_tracker_known_values() -> None:
    t = LatencyTracker(reservoir_size=1000)
    assert math.isnan(t.snapshot().p50_s) and t.snapshot().count == 0
    for k in range(100, 0, -1):  # 100 ms .. 1 ms, unsorted input
        t.add(k / 1000)
    s = t.snapshot()
    assert s.count == 100
    assert s.mean_s == pytest.approx(0.0505)
    assert (s.min_s, s.max_s) == (0.001, 0.1)
    assert s.p50_s == 0.05 and s.p99_s == 0.099  # nearest rank: 50th and 99th of 100


def test_latency_reservoir_is_bounded_but_mean_exact() -> None:
    t = LatencyTracker(reservoir_size=50, seed=3)
    for k in range(10_000):
        t.add(float(k))
    s = t.snapshot()
    assert s.count == 10_000 and s.mean_s == pytest.approx(4999.5)
    assert len(t._reservoir) == 50
    assert 2000 < s.p50_s < 8000  # a uniform sample of 0..9999, seeded


def test_percentile_nearest_rank() -> None:
    assert percentile([1.0, 2.0, 3.0, 4.0], 50) == 2.0
    assert percentile([1.0, 2.0, 3.0, 4.0], 99) == 4.0
    assert percentile([5.0], 1) == 5.0
    assert math.isnan(percentile([], 50))


# ----------------------------------------------------------------- through zenoh
def test_gap_detection_and_typed_iteration(daemon: Daemon) -> None:
    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint]) as sub:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub)
        sent = [rate(s) for s in (0, 1, 2, 5, 6)]
        for msg in sent:
            pub.put(encode_rate(msg))
        got = list(itertools.islice(sub.rates(timeout_s=WAIT_S), 5))
        assert got == sent
        assert all(isinstance(m, RateMessage) for m in got)
        st = sub.stats().rate
        assert (st.received, st.gaps, st.missing, st.resets, st.last_seq) == (5, 1, 2, 0, 6)
        # a publisher restart: seq back to 0 is a reset, not a gap
        for s in (0, 1):
            pub.put(encode_rate(rate(s)))
        assert sub.wait_for(lambda s: s.rate.received == 7, timeout_s=WAIT_S)
        st = sub.stats().rate
        assert (st.gaps, st.missing, st.resets) == (1, 2, 1)


def test_latency_against_known_stamps(daemon: Daemon) -> None:
    now_s = 1_700_000_000.0
    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint], clock=lambda: now_s) as sub:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub)
        for k in range(1, 101):  # latency k ms
            pub.put(encode_rate(rate(k - 1, receive_time_s=now_s - k / 1000)))
        assert sub.wait_for(lambda s: s.rate.received == 100, timeout_s=WAIT_S)
        lat = sub.stats().rate.latency
    assert lat.count == 100
    assert lat.mean_s == pytest.approx(0.0505, abs=1e-6)  # float64 ulp at 1.7e9 s is 2.4e-7 s
    assert lat.p50_s == pytest.approx(0.050, abs=1e-6)  # float64 ulp at 1.7e9 s is 2.4e-7 s
    assert lat.p99_s == pytest.approx(0.099, abs=1e-6)  # float64 ulp at 1.7e9 s is 2.4e-7 s
    assert lat.max_s == pytest.approx(0.100, abs=1e-6)  # float64 ulp at 1.7e9 s is 2.4e-7 s


def test_bad_payloads_are_counted_not_raised(daemon: Daemon) -> None:
    received: list[RateMessage] = []
    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint], on_rate=received.append) as sub:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub)
        good = rate(0)
        state_msg = StateMessage(0, 0.0, 0.0, 20.0, 0.1, 0.0, 0.1, (0.0, 0.0, 0.0))
        for payload in (b"\xc1garbage", msgpack.packb([1, 99]), encode_state(state_msg), b""):
            pub.put(payload)
        pub.put(encode_rate(good))
        assert sub.wait_for(lambda s: s.rate.received == 1 and s.rate.undecodable == 4,
                            timeout_s=WAIT_S)  # fmt: skip
        st = sub.stats().rate
        assert received == [good]
        assert st.undecodable == 4 and st.gaps == 0
        assert st.last_error is not None and st.last_error.startswith("rate payload:")


def test_state_health_callbacks_and_errors_in_callbacks(daemon: Daemon) -> None:
    states: list[StateMessage] = []

    def bad_health_cb(msg: HealthMessage) -> None:
        raise RuntimeError("user bug")

    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint], on_state=states.append,
                    on_health=bad_health_cb) as sub:  # fmt: skip
        with pytest.raises(ConfigError, match="on_state callback"):
            sub.states(timeout_s=0.0)
        pub_s, pub_h = daemon.publisher(daemon.keys.state), daemon.publisher(daemon.keys.health)
        daemon.wait_matched(pub_s)
        daemon.wait_matched(pub_h)
        state = StateMessage(0, 1.0, time.time(), 31.5, 0.05, -2.0, 0.2, (0.01, 0.02, 0.03),
                             StatusFlags.T_CLAMPED)  # fmt: skip
        health = HealthMessage(0, 1.0, time.time(), 12.5, 100, 98, {"decode_error": 2},
                               StatusFlags.NONE, "cal-7")  # fmt: skip
        pub_s.put(encode_state(state))
        pub_h.put(encode_health(health))
        pub_h.put(encode_health(HealthMessage(1, 2.0, time.time(), 13.5, 200, 198, {})))
        assert sub.wait_for(lambda s: s.state.received == 1 and s.health.callback_errors == 2,
                            timeout_s=WAIT_S)  # fmt: skip
        assert states == [state]
        st = sub.stats()
        assert st.health.received == 2 and st.health.gaps == 0
        assert "user bug" in (st.health.last_error or "")


def test_queue_keeps_newest_and_counts_drops(daemon: Daemon) -> None:
    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint], queue_size=2) as sub:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub)
        for s in range(5):
            pub.put(encode_rate(rate(s)))
        assert sub.wait_for(lambda st: st.rate.received == 5, timeout_s=WAIT_S)
        assert [m.seq for m in itertools.islice(sub.rates(timeout_s=WAIT_S), 2)] == [3, 4]
        assert sub.stats().rate.dropped == 3


def test_close_is_idempotent_ends_iteration_and_keeps_given_session(daemon: Daemon) -> None:
    with open_session(connect=[daemon.endpoint]) as session:
        sub = Subscriber(VEHICLE, SENSOR, session=session)
        done = threading.Event()
        out: list[RateMessage] = []

        def consume() -> None:
            out.extend(sub.rates(timeout_s=None))
            done.set()

        thread = threading.Thread(target=consume)
        thread.start()
        sub.close()
        sub.close()
        assert done.wait(WAIT_S) and out == []
        thread.join(WAIT_S)
        assert sub.closed and not session.is_closed()
        assert sub.wait_for(lambda s: False, timeout_s=WAIT_S) is False  # returns at once


def test_owned_session_is_closed() -> None:
    with dead_port() as port:
        sub = Subscriber(VEHICLE, SENSOR, connect=[f"tcp/127.0.0.1:{port}"])
        with sub:
            assert not sub.session.is_closed()
        assert sub.session.is_closed()


def test_invalid_arguments() -> None:
    with pytest.raises(ConfigError, match="vehicle name 'a/b'"):
        Subscriber("a/b", SENSOR)
    with pytest.raises(ConfigError, match="queue_size = 0"):
        Subscriber(VEHICLE, SENSOR, queue_size=0)


def test_query_calibration(daemon: Daemon) -> None:
    health = HealthMessage(3, 5.0, 6.0, 7.0, 8, 8, {}, StatusFlags.NONE, "cal-9")
    info = CalibrationInfo("cal-9", {"coefficients_dps": [1.0, 2.0], "axis": "z"}, health)

    loaded = [True]

    def answer(query: zenoh.Query) -> None:
        with query:
            if loaded[0]:
                query.reply(daemon.keys.calibration, encode_calibration_info(info))
            else:
                query.reply_err(b"no calibration loaded")

    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint]) as sub:
        with pytest.raises(TimeoutError, match="calibration: no reply"):
            sub.query_calibration(timeout_s=0.5)
        daemon.session.declare_queryable(daemon.keys.calibration, answer)
        querier = sub.session.declare_querier(sub.keys.calibration)
        ready = threading.Event()
        listener = querier.declare_matching_listener(lambda s: s.matching and ready.set())
        if querier.matching_status.matching:
            ready.set()
        assert ready.wait(WAIT_S), "queryable never matched"
        listener.undeclare()
        assert sub.query_calibration(timeout_s=WAIT_S) == info
        loaded[0] = False
        with pytest.raises(CalibrationError, match=r"calibration: daemon replied .*no calibration"):
            sub.query_calibration(timeout_s=WAIT_S)


# ----------------------------------------------------------------- listen and example
def test_listen_prints_live_view_and_summary(daemon: Daemon, capsys) -> None:  # type: ignore[no-untyped-def]
    codes: list[int] = []
    argv = ["--vehicle", VEHICLE, "--sensor", SENSOR, "--connect", daemon.endpoint,
            "--count", "20", "--timeout-s", str(WAIT_S * 2), "--max-hz", "0.01"]  # fmt: skip
    thread = threading.Thread(target=lambda: codes.append(listen_main(argv)))
    pub_r, pub_s = daemon.publisher(daemon.keys.rate), daemon.publisher(daemon.keys.state)
    thread.start()
    daemon.wait_matched(pub_s)
    daemon.wait_matched(pub_r)
    state = StateMessage(0, 0.0, time.time(), 25.0, 0.1, 0.5, 0.1, (0.05, 0.1, 0.25))
    pub_s.put(encode_state(state))
    for s in list(range(10)) + list(range(12, 22)):  # one gap of 2
        pub_r.put(encode_rate(rate(s)))
    thread.join(WAIT_S * 3)
    assert codes == [0]
    out = capsys.readouterr().out.splitlines()
    live = [line for line in out if line.startswith("#")]
    assert len(live) == 2  # --max-hz 0.01: the first line, then only the final one
    assert live[-1].startswith("#21 raw[+0.1500 -0.1000 +0.7500] corr[+0.1000 -0.2000 +0.5000]")
    assert "T 25.00 C  dT +0.500 C" in live[-1] and "gaps=1/2" in live[-1]
    assert any("rate: received=20 gaps=1 missing=2" in line for line in out)
    assert any("state: received=1 gaps=0" in line for line in out)


def test_listen_times_out_without_publisher(capsys) -> None:  # type: ignore[no-untyped-def]
    with dead_port() as port:  # nobody listens there
        argv = ["--vehicle", VEHICLE, "--sensor", SENSOR,
                "--connect", f"tcp/127.0.0.1:{port}", "--timeout-s", "0.3"]  # fmt: skip
        code = listen_main(argv)
    assert code == 1
    assert "rate: received=0" in capsys.readouterr().out
    assert listen_main(["--vehicle", "a*", "--sensor", SENSOR, "--timeout-s", "0.1"]) == 2
    assert "vehicle name 'a*' is invalid" in capsys.readouterr().err


def test_servo_loop_example_runs(daemon: Daemon) -> None:
    n = 12
    proc = subprocess.Popen(
        [sys.executable, str(EXAMPLE), "--vehicle", VEHICLE, "--sensor", SENSOR,
         "--connect", daemon.endpoint, "--max-samples", str(n), "--timeout-s", str(WAIT_S * 2)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub, timeout_s=WAIT_S * 2)
        for s in range(n):
            pub.put(encode_rate(rate(s, z_dps=0.1 * s)))
        out, err = proc.communicate(timeout=WAIT_S * 2)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    lines = [line.split() for line in out.splitlines() if line.startswith("seq=")]
    assert len(lines) == n
    for s, fields in enumerate(lines):
        values = dict(f.split("=") for f in fields)
        assert int(values["seq"]) == s
        # command = -gain · corrected yaw rate, gain 2.0 by default
        assert float(values["command_dps"]) == pytest.approx(-2.0 * 0.1 * s, abs=1e-6)


# ------------------------------------------------------------ non-finite samples
def _rate_payload(seq: int, values: list[float]) -> bytes:
    """A rate payload built by hand from the layout (docs/wire-format.md), not encode_rate."""
    out: bytes = msgpack.packb([1, 1, seq, 1.5, time.time(), *values, 0])
    return out


NON_FINITE_CASES = [(i, v) for i in range(9) for v in (math.nan, math.inf, -math.inf)]


@pytest.mark.parametrize(("index", "value"), NON_FINITE_CASES)
def test_decoder_flags_a_non_finite_value_in_any_axis(index: int, value: float) -> None:
    from gyrotherm.codecs._wire_decode import decode_rate

    values = [0.1, -0.2, 0.3, 0.15, -0.1, 0.55, 0.05, 0.1, 0.25]
    values[index] = value
    fast = decode_rate(_rate_payload(3, values))  # all floats: the decoder's fast path
    slow = decode_rate(msgpack.packb([1, 1, 3, 1, 2.0, *values, 0]))  # an int: checked path
    for msg in (fast, slow):
        assert msg.flags == StatusFlags.NON_FINITE
        got = (*msg.rate_dps, *msg.raw_rate_dps, *msg.bias_dps)
        assert math.isnan(got[index]) if math.isnan(value) else got[index] == value


def test_decoder_leaves_finite_samples_alone_even_when_their_sum_overflows() -> None:
    from gyrotherm.codecs._wire_decode import decode_rate

    big = [1e308, 1e308, 1e308, 1e308, 1e308, 0.0, -1e308, 0.0, 0.0]  # sum: inf, all finite
    assert decode_rate(_rate_payload(0, big)).flags == StatusFlags.NONE
    assert decode_rate(_rate_payload(0, [0.0] * 9)).flags == StatusFlags.NONE


def test_subscriber_flags_and_counts_non_finite_rates(daemon: Daemon) -> None:
    received: list[RateMessage] = []
    with Subscriber(VEHICLE, SENSOR, connect=[daemon.endpoint], on_rate=received.append) as sub:
        pub = daemon.publisher(daemon.keys.rate)
        daemon.wait_matched(pub)
        n = 0
        for index, value in NON_FINITE_CASES:
            values = [0.1] * 9
            values[index] = value
            pub.put(_rate_payload(n, values))
            n += 1
        pub.put(_rate_payload(n, [0.1] * 9))  # a clean one last
        assert sub.wait_for(lambda s: s.rate.received == n + 1, timeout_s=WAIT_S)
        st = sub.stats().rate
        assert st.non_finite == len(NON_FINITE_CASES) == n
        assert all(m.flags & StatusFlags.NON_FINITE for m in received[:n])
        assert received[n].flags == StatusFlags.NONE
        assert st.undecodable == 0 and st.gaps == 0
