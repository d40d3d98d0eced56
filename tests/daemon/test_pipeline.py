"""The pipeline: offline equivalence, accounting, bad frames, flags, reload."""

from __future__ import annotations

import math
from dataclasses import replace

import can
import numpy as np
import pytest

from gyrotherm import PublishError
from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, Run, TemperatureSample
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration, features
from gyrotherm.daemon import Pipeline
from gyrotherm.sim import chamber_runs, frames_from_run
from streamkit import RecordingSink, assert_offline_compensation, run_frames


def test_corrected_rates_equal_offline_compensation(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    run = short_runs[0]
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for msg in run_frames(run, FrameEncoder()):
        pipe.process(msg, 1.0e9)
    rates = [decode_rate(p).rate_dps for p in sink.rates]
    offline = assert_offline_compensation(rates, run, stream_calibration)
    c = pipe.counters()
    assert c.frames_received == 2 * len(run) == c.frames_published
    assert c.drops == {}
    states = [decode_state(p) for p in sink.states]
    assert [s.seq for s in states] == list(range(len(run)))
    np.testing.assert_allclose([s.temperature_c for s in states], offline.temperature_c,
                               atol=1e-9)


@pytest.mark.parametrize("rate_hz", [10.0, 50.0])
def test_played_run_equals_offline_compensation_above_the_sensor_rate(
    stream_calibration: Calibration, rate_hz: float
) -> None:
    """The simulator's player sends one temperature frame per sensor refresh (0.1 s),
    not one per row: at 50 Hz rows a reading is held for five rows. The fitter's
    features must fuse it once too, or offline ΔT differs from the daemon's."""
    run = chamber_runs([5], seed=2, rate_hz=rate_hz, hold_s=120)[0].slice(0, int(600 * rate_hz))
    assert run.temperature_period_s() == 0.1
    frames = list(frames_from_run(run, encoder=FrameEncoder()))
    n_temperature = len(frames) - len(run)
    assert n_temperature == pytest.approx(len(run) * 10.0 / rate_hz, abs=1)
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for msg in frames:
        pipe.process(msg, 1.0e9)
    rates = [decode_rate(p).rate_dps for p in sink.rates]
    offline = assert_offline_compensation(rates, run, stream_calibration)
    # the negative control: fusing every row (the old offline rule) is visibly different
    every_row = replace(stream_calibration.estimator, update_period_s=1e-9)
    if rate_hz > 10.0:
        naive = features(run, every_row)
        assert np.max(np.abs(naive.delta_t_c - offline.delta_t_c)) > 0.1


def test_frames_faster_than_the_sensor_refresh_are_fused_once_per_slot(
    stream_calibration: Calibration,
) -> None:
    """A gyro whose temperature refreshes every 1.28 s but is sent with every 10 Hz rate
    frame (the held reading repeated), under a calibration fitted with
    ``update_period_s`` = 1.28 s: the daemon fuses one frame per slot floor(t / 1.28),
    as offline features do, so the corrected rates still equal offline evaluation to
    1e-9 °/s. Fusing every frame (the held value 13 times) was the old daemon rule."""
    run = chamber_runs([5], seed=2, rate_hz=10.0, hold_s=120)[0].slice(0, 6000)
    first = np.r_[0, np.flatnonzero(np.diff(np.floor(run.time_s / 1.28 + 1e-9))) + 1]
    held = np.repeat(run.temperature_c[first], np.diff(np.r_[first, len(run)]))
    run = replace(run, temperature_c=held, metadata={})  # nothing says 1.28 s
    assert run.temperature_period_s() is None
    cal = replace(stream_calibration,
                  estimator=replace(stream_calibration.estimator, update_period_s=1.28))
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal)
    for msg in run_frames(run, FrameEncoder()):  # a temperature frame with every row
        pipe.process(msg, 1.0e9)
    assert pipe.counters().drops == {}
    offline = assert_offline_compensation([decode_rate(p).rate_dps for p in sink.rates], run,
                                          cal)
    # the negative control: fusing every frame (the old daemon rule) is visibly different
    naive = features(run, replace(cal.estimator, update_period_s=1e-9))
    assert np.max(np.abs(naive.delta_t_c - offline.delta_t_c)) > 0.1


def test_every_frame_is_published_or_dropped_by_reason(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    rng = np.random.default_rng(11)
    frames = list(run_frames(short_runs[1].slice(0, 400), FrameEncoder()))
    bad = {"crc_mismatch": 0, "wrong_length": 0, "unknown_id": 0}
    mutated: list[can.Message] = []
    for msg in frames:
        roll = rng.random()
        if roll < 0.05:
            data = bytearray(msg.data)
            data[int(rng.integers(0, 7))] ^= 0x10
            msg = can.Message(arbitration_id=msg.arbitration_id, data=data,
                              is_extended_id=False, timestamp=msg.timestamp)
            bad["crc_mismatch"] += 1
        elif roll < 0.08:
            msg = can.Message(arbitration_id=msg.arbitration_id, data=msg.data[:5],
                              is_extended_id=False, timestamp=msg.timestamp)
            bad["wrong_length"] += 1
        elif roll < 0.10:
            mutated.append(can.Message(arbitration_id=0x7FF, data=b"\x00" * 8,
                                       is_extended_id=False, timestamp=msg.timestamp))
            bad["unknown_id"] += 1
        mutated.append(msg)
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for msg in mutated:
        pipe.process(msg, 0.0)
    c = pipe.counters()
    assert c.frames_received == len(mutated)
    assert c.frames_received == c.frames_published + sum(c.drops.values())
    for reason, n in bad.items():
        assert c.drops.get(reason, 0) == n, reason
    assert c.rate_published == len(sink.rates) and c.state_published == len(sink.states)
    # frames after a lost one carry the COUNTER_JUMP flag, and their seq stays gap-free
    rates = [decode_rate(p) for p in sink.rates]
    assert [r.seq for r in rates] == list(range(len(rates)))
    assert any(r.flags & StatusFlags.COUNTER_JUMP for r in rates)


class FailingSink(RecordingSink):
    def put_rate(self, payload: bytes) -> None:
        raise PublishError("rate: session closed")


def test_publish_errors_are_counted_not_raised(short_runs: list[Run]) -> None:
    pipe = Pipeline(FrameDecoder(), FailingSink(), calibration=None)
    for msg in run_frames(short_runs[0].slice(0, 10), FrameEncoder()):
        pipe.process(msg, 0.0)
    c = pipe.counters()
    assert c.drops == {"publish_error": 10}
    assert c.frames_published == 10  # the state messages


class UnmatchedSink(RecordingSink):
    """Sends every payload but reports "no subscriber matched" while ``matched`` is False."""

    def __init__(self) -> None:
        super().__init__()
        self.matched = True
        self.delivered: list[bytes] = []

    def put_rate(self, payload: bytes) -> bool:
        super().put_rate(payload)
        if self.matched:
            self.delivered.append(payload)
        return self.matched

    def put_state(self, payload: bytes) -> bool:
        super().put_state(payload)
        return self.matched


def test_unmatched_messages_are_dropped_as_no_subscriber_and_spend_their_seq(
    short_runs: list[Run],
) -> None:
    sink = UnmatchedSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=None)
    frames = list(run_frames(short_runs[0].slice(0, 30), FrameEncoder()))  # 30 temp + 30 rate
    for i, msg in enumerate(frames):
        sink.matched = not 20 <= i < 40  # rows 10..19 go out while nobody listens
        pipe.process(msg, 0.0)
    c = pipe.counters()
    assert c.drops == {"no_subscriber": 20}
    assert c.frames_received == 60 == c.frames_published + 20
    assert c.rate_published == 20 and c.state_published == 20
    # every message went out with its own seq: a subscriber sees 10 missing rates
    assert [decode_rate(p).seq for p in sink.rates] == list(range(30))
    seen = [decode_rate(p).seq for p in sink.delivered]
    assert seen == [*range(10), *range(20, 30)]


def test_flags_before_temperature_without_calibration_and_when_stale(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    enc = FrameEncoder()
    frames = [m for m in run_frames(short_runs[0].slice(0, 60), enc)]
    rate_only = [m for m in frames if m.arbitration_id == 0x120]
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=None)
    pipe.process(rate_only[0], 0.0)
    first = decode_rate(sink.rates[0])
    assert first.flags & StatusFlags.TEMPERATURE_STALE and first.flags & StatusFlags.NO_CALIBRATION
    assert first.bias_dps == (0.0, 0.0, 0.0) and first.rate_dps == first.raw_rate_dps
    # with calibration: after 60 s of temperature, then rate frames only for > stale_after_s
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for m in frames:
        pipe.process(m, 0.0)
    fresh = decode_rate(sink.rates[-1])
    assert not fresh.flags & (StatusFlags.TEMPERATURE_STALE | StatusFlags.NO_CALIBRATION)
    later = short_runs[0].slice(60, 80)
    for i, t in enumerate(later.time_s.tolist()):
        from gyrotherm.codecs import RateSample

        pipe.process(enc.encode_rate(RateSample(t, *(float(later.rates_dps[a][i])
                                                     for a in "xyz"))), 0.0)
    pipe.tick()  # predict-only
    stale = decode_rate(sink.rates[-1])
    assert stale.flags & StatusFlags.TEMPERATURE_STALE
    assert pipe.last_estimate is not None and pipe.last_estimate.stale
    assert math.isfinite(stale.bias_dps[0])


def test_clamped_flag_outside_calibrated_range(stream_calibration: Calibration) -> None:
    from gyrotherm.codecs import RateSample, TemperatureSample

    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    hot = stream_calibration.valid_range.t_max_c + 20
    for k in range(30):
        pipe.process(enc.encode_temperature(TemperatureSample(k * 1.0, hot)), 0.0)
        pipe.process(enc.encode_rate(RateSample(k * 1.0, 0.1, 0.2, 0.3)), 0.0)
    last = decode_rate(sink.rates[-1])
    assert last.flags & StatusFlags.T_CLAMPED
    edge = stream_calibration.bias_at(stream_calibration.valid_range.t_max_c, 0.0)
    assert last.bias_dps[0] == pytest.approx(edge.bias_dps["x"], abs=0.01)


def test_set_calibration_swaps_atomically(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=None)
    frames = list(run_frames(short_runs[0].slice(0, 40), FrameEncoder()))
    for m in frames[:40]:
        pipe.process(m, 0.0)
    assert decode_rate(sink.rates[-1]).flags & StatusFlags.NO_CALIBRATION
    pipe.set_calibration(stream_calibration)
    for m in frames[40:]:
        pipe.process(m, 0.0)
    after = decode_rate(sink.rates[-1])
    assert not after.flags & StatusFlags.NO_CALIBRATION
    assert after.bias_dps != (0.0, 0.0, 0.0)


def test_health_counts_counter_jumps_of_both_messages(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    frames = list(run_frames(short_runs[0].slice(0, 40), FrameEncoder()))
    kinds = [("temperature" if i % 2 == 0 else "rate") for i in range(len(frames))]
    assert kinds[:2] == ["temperature", "rate"]  # run_frames: temperature, then rate, per row
    lost = {10, 21, 22}  # one temperature frame; one rate frame and the next temperature
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for i, msg in enumerate(frames):
        if i not in lost:
            pipe.process(msg, 0.0)
    health = pipe.health(seq=0, receive_time_s=0.0, uptime_s=1.0, calibration_id="c")
    # temperature counters jump after frames 10 and 22, the rate counter after frame 21
    assert health.counter_jumps == pipe.counters().counter_jumps == 3
    assert health.drops == {}  # "deliver": jumps are counted, the frames still published
    flagged = [decode_rate(p).flags & StatusFlags.COUNTER_JUMP for p in sink.rates]
    assert sum(1 for f in flagged if f) == 1


def test_a_nonzero_device_status_is_flagged_until_it_clears(
    stream_calibration: Calibration,
) -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    statuses = [0, 0, 5, 5, 0]  # the shipped DBC: 0 = OK, other values device faults
    for k, status in enumerate(statuses):
        t = 0.1 * k
        pipe.process(enc.encode_temperature(TemperatureSample(t, 25.0, status)), 0.0)
        pipe.process(enc.encode_rate(RateSample(t, 0.1, 0.2, 0.3)), 0.0)
    states = [decode_state(p) for p in sink.states]
    rates = [decode_rate(p) for p in sink.rates]
    want = [bool(s) for s in statuses]
    assert [bool(m.flags & StatusFlags.SENSOR_FAULT) for m in states] == want
    assert [bool(m.flags & StatusFlags.SENSOR_FAULT) for m in rates] == want
    assert [m.temperature_c for m in states] == pytest.approx([25.0] * 5, abs=0.01)
