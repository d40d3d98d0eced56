"""Absurd frame time stamps cannot poison the pipeline (its module docstring, "Time stamps").

Independent truth: a second pipeline fed the same sane stream without the bad frames.
Every stream here is re-encoded in its final order by a fresh encoder, so the CAN
counters are consecutive and only the time stamps differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import can
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, Run, TemperatureSample
from gyrotherm.codecs._wire import RateMessage, StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Pipeline
from gyrotherm.daemon._pipeline import MAX_TIME_JUMP_S, TIME_BASE_FRAMES
from streamkit import RecordingSink

BASE_S = 1.7e9  # socketcan-like epoch stamps: 0 and 5e-324 lie far in the past
RECEIVE_S = 1.7e9
K = TIME_BASE_FRAMES
W = MAX_TIME_JUMP_S
STALE = StatusFlags.TEMPERATURE_STALE
ABSURD = [1e300, -1e300, 1e308, -1e308, 5e-324, -5e-324, 0.0, math.nan, math.inf, -math.inf]
# relative to the latest sane stamp: repeats and steps back (a rate frame inside the
# window is believed and published), and forward jumps beyond the window
RELATIVE = [0.0, -0.5, -10.0, -(W - 1.0), -(W + 1.0), -1e3, -1e6, -BASE_S,
            W + 1.0, 1e3, 1e6, 1e9, 1e12, 1e15]


@dataclass(frozen=True)
class Frame:
    kind: str  # "T" or "R"
    time_s: float
    values: tuple[float, ...]
    sane: bool = True


def sane_frames(run: Run, rows: int, base_s: float = BASE_S) -> list[Frame]:
    out: list[Frame] = []
    r = run.rates_dps
    for i in range(rows):
        t = base_s + float(run.time_s[i])
        out.append(Frame("T", t, (float(run.temperature_c[i]),)))
        out.append(Frame("R", t, (float(r["x"][i]), float(r["y"][i]), float(r["z"][i]))))
    return out


def encode(frames: list[Frame]) -> list[can.Message]:
    enc = FrameEncoder()
    return [enc.encode_temperature(TemperatureSample(f.time_s, f.values[0])) if f.kind == "T"
            else enc.encode_rate(RateSample(f.time_s, *f.values)) for f in frames]


@dataclass
class Played:
    pipe: Pipeline
    sink: RecordingSink
    rates: list[RateMessage | None]  # per frame: the rate message it produced, if any
    stale_while_dropping: list[bool]


def play(frames: list[Frame], calibration: Calibration | None) -> Played:
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=calibration)
    rates: list[RateMessage | None] = []
    stale: list[bool] = []
    for f, msg in zip(frames, encode(frames), strict=True):
        n_rates, drops = len(sink.rates), sum(pipe.counters().drops.values())
        pipe.process(msg, RECEIVE_S)
        pipe.tick()
        rates.append(decode_rate(sink.rates[-1]) if len(sink.rates) > n_rates else None)
        if f.kind == "T" and sum(pipe.counters().drops.values()) > drops:
            health = pipe.health(seq=0, receive_time_s=RECEIVE_S, uptime_s=1.0,
                                 calibration_id="")
            stale.append(bool(pipe.flags & STALE) and bool(health.flags & STALE))
    return Played(pipe, sink, rates, stale)


def same_but_seq(a: RateMessage, b: RateMessage, extra_flags: StatusFlags) -> bool:
    return (a.sensor_time_s, a.receive_time_s, a.rate_dps, a.raw_rate_dps, a.bias_dps,
            a.flags) == (b.sensor_time_s, b.receive_time_s, b.rate_dps, b.raw_rate_dps,
                         b.bias_dps, b.flags | extra_flags)


stamp = st.one_of(st.sampled_from(ABSURD).map(lambda v: ("abs", v)),
                  st.sampled_from(RELATIVE).map(lambda v: ("rel", v)))
bad_frame = st.tuples(st.sampled_from("TR"), stamp,
                      st.floats(-40.0, 125.0), st.floats(-60.0, 60.0))
# row -> (before its temperature frame?, burst)
bursts = st.dictionaries(st.integers(1, 35), st.tuples(st.booleans(),
                         st.lists(bad_frame, min_size=1, max_size=K - 1)), max_size=12)


def inject(clean: list[Frame], plan: dict[int, tuple[bool, list]]) -> list[Frame]:  # type: ignore[type-arg]
    """Insert the bursts; a stream never gets K bad frames in a row (that would be a
    time base change, tested below), so extra ones are left out."""
    out: list[Frame] = []
    bad_since_sane = {"T": 0, "R": 0}
    for j, f in enumerate(clean):
        row, is_t = divmod(j, 2)[0], f.kind == "T"
        before, burst = plan.get(row, (True, []))
        if burst and before == is_t:
            last_sane = out[-1].time_s
            for kind, (how, v), temp, rate in burst:
                if bad_since_sane[kind] == K - 1:
                    continue
                bad_since_sane[kind] += 1
                t = v if how == "abs" else last_sane + v
                values = (temp,) if kind == "T" else (rate, -rate, 0.5 * rate)
                out.append(Frame(kind, t, values, sane=False))
        out.append(f)
        bad_since_sane[f.kind] = 0
    return out


@settings(derandomize=True, max_examples=60, deadline=None, database=None,
          phases=(Phase.explicit, Phase.generate))  # no shrinking: bounded run time
@given(plan=bursts)
def test_bad_stamps_never_change_what_the_sane_stream_gives(
    short_runs: list[Run], stream_calibration: Calibration, plan: dict  # type: ignore[type-arg]
) -> None:
    clean_frames = sane_frames(short_runs[0], 40)
    dirty_frames = inject(clean_frames, plan)
    clean = play(clean_frames, stream_calibration)
    dirty = play(dirty_frames, stream_calibration)

    c = dirty.pipe.counters()
    assert set(c.drops) <= {"bad_timestamp"}  # never internal_error
    assert c.frames_received == len(dirty_frames)
    assert c.frames_received == c.frames_published + sum(c.drops.values())
    bad_published = sum(1 for f, m in zip(dirty_frames, dirty.rates, strict=True)
                        if not f.sane and m is not None)
    n_bad = sum(not f.sane for f in dirty_frames)
    assert c.drops.get("bad_timestamp", 0) == n_bad - bad_published
    newest_rate_s = -math.inf  # the rate window's reference: the largest accepted stamp
    for f, m in zip(dirty_frames, dirty.rates, strict=True):
        if m is not None and not f.sane:  # a bad frame that was believed: in the window
            assert f.kind == "R" and -W <= f.time_s - newest_rate_s <= W
        if m is not None:
            assert m.sensor_time_s == f.time_s
            newest_rate_s = max(newest_rate_s, f.time_s)
    assert dirty.pipe.time_base_changes == {"rate": 0, "temperature": 0}

    # every sane frame gives exactly what it gives in the clean run (no recovery delay);
    # rate flags add TEMPERATURE_STALE while the latest temperature frame was dropped
    assert dirty.sink.states == clean.sink.states
    clean_rates = [m for m in clean.rates if m is not None]
    dirty_rates: list[tuple[RateMessage, bool]] = []
    dropping = False
    for f, m in zip(dirty_frames, dirty.rates, strict=True):
        if f.kind == "T":
            dropping = not f.sane  # every bad temperature frame is dropped
        elif f.sane:
            assert m is not None
            dirty_rates.append((m, dropping))
    assert len(dirty_rates) == len(clean_rates) == 40
    for (got, dropping), want in zip(dirty_rates, clean_rates, strict=True):
        assert same_but_seq(got, want, STALE if dropping else StatusFlags.NONE), (got, want)
    assert all(dirty.stale_while_dropping)

    est = dirty.pipe.last_estimate
    assert est is not None
    assert all(math.isfinite(v) for v in (est.temperature_c, est.delta_t_c,
                                          est.temperature_std_c, est.delta_t_std_c))


@pytest.mark.parametrize("jump_s", [-BASE_S, -1e4, -3 * W, 3 * W, 1e5, 3e7])
def test_a_sustained_time_base_change_is_taken_after_k_frames_per_stream(
    short_runs: list[Run], stream_calibration: Calibration, jump_s: float
) -> None:
    """A sensor reboot / clock step: K−1 frames per stream are dropped (stale meanwhile),
    the K-th restarts the estimator; from there on the messages are those of a fresh
    pipeline started on that frame."""
    run = short_runs[0]
    before = sane_frames(run, 30)
    after_base = BASE_S + jump_s
    after = sane_frames(run.slice(30, 70), 40, base_s=after_base)
    frames = before + after
    played = play(frames, stream_calibration)
    c = played.pipe.counters()
    assert c.drops == {"bad_timestamp": 2 * (K - 1)}
    assert played.pipe.time_base_changes == {"rate": 1, "temperature": 1}
    assert len(played.stale_while_dropping) == K - 1 and all(played.stale_while_dropping)
    # rows of the new base: T, R, T, R, ...; the K-th rate frame is the first published
    assert [m is None for m in played.rates[60:60 + 2 * K]] == [True] * (2 * K - 1) + [False]
    fresh = play(after[2 * (K - 1):], stream_calibration)
    got = [m for m in played.rates[60 + 2 * (K - 1):] if m is not None]
    want = [m for m in fresh.rates if m is not None]
    assert len(got) == len(want) == 40 - (K - 1)
    for g, w in zip(got, want, strict=True):
        assert same_but_seq(g, w, StatusFlags.NONE)
    assert got[0].flags & StatusFlags.ESTIMATOR_WARMUP  # the estimator restarted
    n_states = len(fresh.sink.states)
    assert [decode_state(p).temperature_c for p in played.sink.states[-n_states:]] == [
        decode_state(p).temperature_c for p in fresh.sink.states]


def test_the_testers_case_one_temperature_frame_at_minus_1e300(
    stream_calibration: Calibration,
) -> None:
    frames = [Frame("T", BASE_S + k, (20.0,)) for k in range(5)]
    frames.append(Frame("T", -1e300, (20.0,), sane=False))
    frames += [Frame(kind, BASE_S + k, (20.0,) if kind == "T" else (0.1, 0.2, 0.3))
               for k in range(5, 30) for kind in "TR"]
    played = play(frames, stream_calibration)
    c = played.pipe.counters()
    assert c.drops == {"bad_timestamp": 1}
    assert c.state_published == 5 + 25 and c.rate_published == 25
    assert played.stale_while_dropping == [True]
    assert not decode_state(played.sink.states[-1]).flags & StatusFlags.TEMPERATURE_STALE
    assert decode_state(played.sink.states[-1]).sensor_time_s == BASE_S + 29


@pytest.mark.parametrize("bad_s", [1e300, -1e300, BASE_S + 1e6, math.nan, math.inf])
def test_an_absurd_rate_stamp_reaches_neither_staleness_nor_predict_only(
    stream_calibration: Calibration, bad_s: float
) -> None:
    frames = [Frame(kind, BASE_S + k, (20.0,) if kind == "T" else (0.1, 0.2, 0.3))
              for k in range(10) for kind in "TR"]
    frames.append(Frame("R", bad_s, (0.1, 0.2, 0.3), sane=False))
    played = play(frames, stream_calibration)
    pipe = played.pipe
    assert pipe.counters().drops == {"bad_timestamp": 1}
    assert pipe.last_sensor_time_s == BASE_S + 9
    est = pipe.last_estimate
    assert est is not None and est.time_s == BASE_S + 9 and not est.stale
    assert not pipe.flags & StatusFlags.TEMPERATURE_STALE


@pytest.mark.parametrize("first_s", [math.nan, 1e300, -1e308])
def test_an_absurd_first_stamp_is_dropped_not_taken_as_the_reference(
    stream_calibration: Calibration, first_s: float
) -> None:
    frames = [Frame("T", first_s, (20.0,), sane=False), Frame("R", first_s, (0.1, 0.2, 0.3),
                                                               sane=False)]
    frames += [Frame(kind, BASE_S + k, (20.0,) if kind == "T" else (0.1, 0.2, 0.3))
               for k in range(3) for kind in "TR"]
    played = play(frames, stream_calibration)
    assert played.pipe.counters().drops == {"bad_timestamp": 2}
    assert played.pipe.counters().frames_published == 6


def test_window_arguments_are_checked() -> None:
    from gyrotherm import ConfigError

    with pytest.raises(ConfigError, match="max_time_jump_s = nan"):
        Pipeline(FrameDecoder(), RecordingSink(), calibration=None, max_time_jump_s=math.nan)
    with pytest.raises(ConfigError, match="time_base_frames = 1"):
        Pipeline(FrameDecoder(), RecordingSink(), calibration=None, time_base_frames=1)


def test_predict_only_covers_at_most_the_window_after_the_last_temperature_frame(
    stream_calibration: Calibration,
) -> None:
    """Temperature frames stop, rate frames go on for 3·W: tick() predicts while the
    gap is in (stale_after_s, W], then holds the estimate (still stale)."""
    frames = [Frame(kind, BASE_S + k, (20.0,) if kind == "T" else (0.1, 0.2, 0.3))
              for k in range(30) for kind in "TR"]
    frames += [Frame("R", BASE_S + 29 + k, (0.1, 0.2, 0.3)) for k in range(1, int(3 * W))]
    played = play(frames, stream_calibration)
    est = played.pipe.last_estimate
    assert est is not None and est.stale
    assert est.time_s == BASE_S + 29 + W  # the last prediction: W after the last reading
    assert played.pipe.flags & StatusFlags.TEMPERATURE_STALE
    assert played.rates[-1] is not None and played.rates[-1].flags & STALE


@pytest.mark.parametrize("silence_s", [W + 1.0, 600.0, 86_400.0])
def test_a_gyro_that_falls_silent_and_resumes_loses_no_frame(silence_s: float) -> None:
    """A forward jump no larger than W + the wall-clock time that passed is believed:
    the bus was silent, not lying (module docstring). Control: the same jump with
    no wall-clock time passing is dropped until the time base change is recognised."""
    frames = encode([Frame("T", BASE_S + 0.1 * i, (20.0 + 0.01 * i,)) if i % 2 == 0
                     else Frame("R", BASE_S + 0.1 * i, (0.1, 0.2, 0.3)) for i in range(20)]
                    + [Frame("T", BASE_S + silence_s + 0.1 * i, (25.0,)) if i % 2 == 0
                       else Frame("R", BASE_S + silence_s + 0.1 * i, (0.1, 0.2, 0.3))
                       for i in range(20, 40)])

    def drops_when(wall_gap_s: float) -> dict[str, int]:
        pipe = Pipeline(FrameDecoder(), RecordingSink(), calibration=None)
        for i, msg in enumerate(frames):
            pipe.process(msg, RECEIVE_S + 0.1 * i + (wall_gap_s if i >= 20 else 0.0))
        c = pipe.counters()
        assert c.frames_received == 40 == c.frames_published + sum(c.drops.values())
        return c.drops

    assert drops_when(silence_s) == {}  # every frame published, as after a real silence
    lost = drops_when(0.0)  # the stamps jumped but no time passed: not believed at once
    assert lost == {"bad_timestamp": 2 * (K - 1)}
