"""Frames that cannot be handled are dropped by reason; the stream and accounting go on."""

from __future__ import annotations

import can

from gyrotherm.codecs import (
    FrameDecoder,
    FrameEncoder,
    RateSample,
    Run,
    StatusFlags,
    TemperatureSample,
    decode_rate,
    decode_state,
)
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Pipeline
from streamkit import RecordingSink, run_frames


def _restamp(msg: can.Message, t: float) -> can.Message:
    return can.Message(arbitration_id=msg.arbitration_id, data=msg.data,
                       is_extended_id=False, timestamp=t)


def _balanced(pipe: Pipeline) -> bool:
    c = pipe.counters()
    return c.frames_received == c.frames_published + sum(c.drops.values())


def test_non_finite_timestamps_are_dropped_and_do_not_poison_the_filter(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    frames = list(run_frames(short_runs[0].slice(0, 100), FrameEncoder()))
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for k, msg in enumerate(frames):
        if k in (41, 60):
            msg = _restamp(msg, float("nan"))
        elif k == 81:
            msg = _restamp(msg, float("inf"))
        pipe.process(msg, 0.0)
        pipe.tick()
    assert pipe.counters().drops == {"bad_timestamp": 3}
    assert _balanced(pipe)
    last = decode_state(sink.states[-1])
    assert abs(last.temperature_c - float(short_runs[0].temperature_c[99])) < 0.5
    assert decode_rate(sink.rates[-1]).sensor_time_s == float(short_runs[0].time_s[99])


class ExplodingSink(RecordingSink):
    """A sink with a bug: every 10th rate publish raises something unexpected."""

    def put_rate(self, payload: bytes) -> None:
        if len(self.rates) % 10 == 9:
            self.rates.append(b"")
            raise RuntimeError("bug in a sink")
        self.rates.append(payload)


def test_unexpected_exceptions_are_counted_and_the_stream_goes_on(
    short_runs: list[Run], stream_calibration: Calibration
) -> None:
    pipe = Pipeline(FrameDecoder(), ExplodingSink(), calibration=stream_calibration)
    for msg in run_frames(short_runs[0].slice(0, 50), FrameEncoder()):
        pipe.process(msg, 0.0)
    c = pipe.counters()
    assert c.drops == {"internal_error": 5}
    assert c.rate_published == 45 and c.state_published == 50
    assert _balanced(pipe)


def test_absurd_but_finite_timestamp_is_contained() -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=None)
    for k in range(5):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0)), 0.0)
    pipe.process(enc.encode_temperature(TemperatureSample(1e103, 20.0)), 0.0)
    pipe.process(enc.encode_rate(RateSample(1e103, 0.1, 0.2, 0.3)), 0.0)
    pipe.tick()  # must not raise
    for k in range(5, 10):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0)), 0.0)
    assert _balanced(pipe)
    assert pipe.counters().drops.get("internal_error", 0) <= 1


def test_warmup_flag_returns_after_the_estimator_restarts(stream_calibration: Calibration) -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for k in range(40):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0)), 0.0)
    assert not decode_state(sink.states[-1]).flags & StatusFlags.ESTIMATOR_WARMUP
    for k in range(40, 50):  # a real 15 °C step: gated, then re-initialised
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 35.0)), 0.0)
    flags = [decode_state(p).flags for p in sink.states[40:]]
    assert any(f & StatusFlags.ESTIMATOR_WARMUP for f in flags)


def test_reject_policy_counts_a_jump_once(short_runs: list[Run]) -> None:
    frames = list(run_frames(short_runs[0].slice(0, 30), FrameEncoder()))
    del frames[21]  # lose one rate frame (rate frames sit at odd positions)
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(on_counter_jump="reject"), sink, calibration=None,
                    check_counters=False)
    for msg in frames:
        pipe.process(msg, 0.0)
    assert pipe.counters().drops == {"counter_jump": 1}
    assert not any(decode_rate(p).flags & StatusFlags.COUNTER_JUMP for p in sink.rates)
    assert _balanced(pipe)
