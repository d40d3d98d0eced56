"""Power cycles whichever frame comes first, clock steps and time jumps: the daemon
never publishes a rate with a stale boot-time zero under clean flags.

The gyro at rest (the simulator's 1-Hz chamber run, its switch-on offset included)
is powered off for 45 s (> power_on_gap_s = 30 s) and powered on with 0.1 °/s more
offset on every axis. Whatever frame arrives first after the silence (temperature,
rate, or a run of rate frames seconds before the first temperature frame), every
message after the silence carries ZERO_PENDING (or is uncorrected and flagged
TEMPERATURE_STALE | ESTIMATOR_WARMUP) until a new zero is taken, and the new zero
is the hand-computed mean of the second window, 0.1 °/s above the first.
"""

from __future__ import annotations

from dataclasses import replace

import can
import numpy as np
import pytest

from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration, ZeroConfig, ZeroStatus
from gyrotherm.daemon import Pipeline
from streamkit import RecordingSink, run_frames

ZERO = ZeroConfig(window_s=30.0, settle_s=20.0, max_std_dps=0.5, max_step_dps=0.05,
                  max_offset_dps=1.0, deadline_s=600.0)
PENDING, FAILED = StatusFlags.ZERO_PENDING, StatusFlags.ZERO_FAILED
UNVERIFIED = StatusFlags.ZERO_UNVERIFIED
NOT_CORRECTED = StatusFlags.TEMPERATURE_STALE | StatusFlags.ESTIMATOR_WARMUP
TEMPERATURE_ID = FrameEncoder().layout.temperature.frame_id


def _pipe(cal: Calibration, frames: list[can.Message], *, wall: str = "constant"
          ) -> tuple[Pipeline, RecordingSink]:
    """``frames`` through a pipeline; the receive clock: ``constant`` (1e9 s: no wall time
    passes), ``sensor`` (the frame's stamp: a stream received in real time, its silences
    seen by the wall clock too) or ``rows`` (one second per temperature frame: a clock
    that ticks on while the stamps may jump)."""
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal, zero=ZERO)
    rows = 0
    for msg in frames:
        rows += msg.arbitration_id == TEMPERATURE_ID
        rx = {"constant": 1.0e9, "sensor": 1.0e9 + msg.timestamp, "rows": 1.0e9 + rows}[wall]
        pipe.process(msg, rx)
    return pipe, sink


def _second_power_on(run: Run, order: str) -> list[can.Message]:
    """The run, 45 s of silence, the run again (+0.1 °/s); ``order``: which frames of
    the second run come first."""
    later = replace(run, time_s=run.time_s + run.time_s[-1] + 45.0,
                    rates_dps={a: v + 0.1 for a, v in run.rates_dps.items()})
    second = list(run_frames(later, FrameEncoder()))
    if order == "rate_first":  # the first row's rate frame before its temperature frame
        second[0], second[1] = second[1], second[0]
    elif order == "rates_for_5_s":  # temperature frames only from the 6th row on
        second = [m for m in second if not (m.arbitration_id == TEMPERATURE_ID
                                            and m.timestamp < later.time_s[5])]
    return list(run_frames(run, FrameEncoder())) + second


@pytest.mark.parametrize("order", ["temperature_first", "rate_first", "rates_for_5_s"])
def test_a_power_cycle_is_detected_whichever_frame_comes_first(
        short_runs: list[Run], stream_calibration: Calibration, order: str) -> None:
    run = short_runs[0].slice(0, 200)
    pipe, sink = _pipe(stream_calibration, _second_power_on(run, order), wall="sensor")
    assert pipe.counters().drops == {}
    msgs = [decode_rate(p) for p in sink.rates]
    assert len(msgs) == 400
    flags = [m.flags for m in msgs]
    assert not any(f & (PENDING | FAILED | UNVERIFIED) for f in flags[50:200])  # first zero
    done2 = 200 + next(k for k, f in enumerate(flags[200:]) if not f & (PENDING | NOT_CORRECTED))
    # every message between the power-on and the new zero is flagged, none is clean
    assert all(f & PENDING for f in flags[200:done2])
    assert not any(f & (PENDING | FAILED | UNVERIFIED) for f in flags[done2:])
    start = 5 if order == "rates_for_5_s" else 0
    t2 = run.time_s - run.time_s[0]
    window = 200 + np.flatnonzero((t2 >= 20.0) & (t2 < 50.0))
    assert done2 == 200 + int(np.flatnonzero(t2 >= 50.0)[0])
    raw = np.array([m.raw_rate_dps for m in msgs])
    model = np.array([m.bias_dps for m in msgs])
    states = [decode_state(p) for p in sink.states]
    z1 = np.array(states[100].zero.offset_dps)  # type: ignore[union-attr]
    z2 = np.array(states[-1].zero.offset_dps)  # type: ignore[union-attr]
    np.testing.assert_allclose(z2, (raw[window] - model[window]).mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(z2 - z1, 0.1, atol=0.01)
    # uncorrected (bias 0, flagged) only while no temperature frame came after the silence
    for m in msgs[200:200 + start]:
        assert m.bias_dps == (0.0, 0.0, 0.0) and m.flags & NOT_CORRECTED
    assert pipe.compensation.power_on_s == run.time_s[-1] + 45.0 + run.time_s[0]


@pytest.mark.parametrize(("wall", "unverified"), [("rows", True), ("sensor", False)])
def test_a_stamp_jump_the_wall_clock_did_not_see_is_an_untrusted_power_on(
        short_runs: list[Run], stream_calibration: Calibration, wall: str,
        unverified: bool) -> None:
    """The stamps jump +40 s at row 150 (> power_on_gap_s 30 s, inside the 60-s window)
    and the gyro turns steadily at 0.3 °/s from there. Seen by the wall clock too
    (``sensor``) it is a power cycle: a trusted zero takes the turn for an offset, as
    documented. A wall clock that kept ticking a second per row (``rows``) says the stamps
    jumped (a clock step): the power-on's zero is untrusted and ends ZERO_UNVERIFIED."""
    run = short_runs[0].slice(0, 300)
    pipe, sink = _pipe(stream_calibration, _clock_step(run, 150, 40.0, 0.3), wall=wall)
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    assert pipe.compensation.power_on_s == run.time_s[150] + 40.0
    last = decode_rate(sink.rates[-1])
    assert bool(last.flags & UNVERIFIED) is unverified
    assert not last.flags & (PENDING | FAILED)


def test_a_silence_of_the_rates_alone_is_not_a_power_on(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """Rate frames silent for 40 s while temperature frames keep coming: the same zero."""
    run = short_runs[0].slice(0, 300)
    frames = [m for m in run_frames(run, FrameEncoder())
              if m.arbitration_id == TEMPERATURE_ID
              or not 150.0 <= m.timestamp - run.time_s[0] < 190.0]
    pipe, sink = _pipe(stream_calibration, frames)
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    assert zero.done_s == run.time_s[50] and pipe.compensation.power_on_s == run.time_s[0]
    assert not any(decode_rate(p).flags & PENDING for p in sink.rates[60:])


def _clock_step(run: Run, cut: int, step_s: float, extra_dps: float, *,
                temperature_period_s: float = 0.0) -> list[can.Message]:
    moved = replace(run, time_s=np.where(np.arange(len(run)) >= cut, run.time_s + step_s,
                                         run.time_s),
                    rates_dps={a: np.where(np.arange(len(run)) >= cut, v + extra_dps, v)
                               for a, v in run.rates_dps.items()})
    return list(run_frames(moved, FrameEncoder(), period_s=temperature_period_s))


@pytest.mark.parametrize(("extra_dps", "unverified"), [(0.0, False), (0.3, True)])
def test_a_clock_step_re_zeroes_untrusted(short_runs: list[Run],
                                          stream_calibration: Calibration,
                                          extra_dps: float, unverified: bool) -> None:
    """The sensor's clock steps by +1e5 s at row 150 (a clock step or a reboot: the
    daemon cannot tell). The zero is measured again; at rest it agrees with the old one
    (within max_step_dps) and is clean, while a slow steady turn of 0.3 °/s from the
    step on is taken but flagged ZERO_UNVERIFIED until the next power-on."""
    run = short_runs[0].slice(0, 300)
    pipe, sink = _pipe(stream_calibration, _clock_step(run, 150, 1e5, extra_dps))
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    assert pipe.time_base_changes == {"rate": 1, "temperature": 1}
    msgs = [decode_rate(p) for p in sink.rates]
    last = msgs[-1]
    assert bool(last.flags & UNVERIFIED) is unverified
    assert not last.flags & (PENDING | FAILED)
    assert not any(m.flags & FAILED for m in msgs)


def test_a_time_jump_while_pending_never_reports_failed(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """The clock steps by +1e6 s at row 10, while the zero is still pending, and the
    temperature frames come every 4 s: the rate stream takes the new time base frames
    before the temperature stream does. No message carries ZERO_FAILED (before, the
    deadline counted the jump until the temperature's power-on), and the zero is taken."""
    run = short_runs[0].slice(0, 200)
    frames = _clock_step(run, 10, 1e6, 0.0, temperature_period_s=4.0)
    pipe, sink = _pipe(stream_calibration, frames)
    assert pipe.time_base_changes == {"rate": 1, "temperature": 1}
    assert not any(decode_rate(p).flags & FAILED for p in sink.rates)
    assert not any(decode_state(p).flags & FAILED for p in sink.states)
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE


def test_a_reload_while_pending_restarts_the_window(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """Another calibration (x's constant +0.04 °/s) loaded at row 35, inside the 20–50 s
    window: the window starts again on the new model's residuals, so z is the mean of
    raw − bias over rows 35–64 of the daemon's own messages (the new model's bias), not a
    mix of both models' residuals."""
    import dataclasses

    run = short_runs[0].slice(0, 120)
    frames = list(run_frames(run, FrameEncoder()))
    pipe, sink = _pipe(stream_calibration, frames[:70])  # rows 0..34
    coef = dict(stream_calibration.coefficients)
    coef["x"] = (*coef["x"][:-1], coef["x"][-1] + 0.04)
    pipe.set_calibration(dataclasses.replace(stream_calibration, coefficients=coef))
    for msg in frames[70:]:
        pipe.process(msg, 1.0e9)
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    t = run.time_s - run.time_s[0]
    assert zero.done_s == run.time_s[int(np.flatnonzero(t >= 65.0)[0])]
    msgs = [decode_rate(p) for p in sink.rates]
    rows = np.flatnonzero((t >= 35.0) & (t < 65.0))
    raw = np.array([msgs[i].raw_rate_dps for i in rows])
    model = np.array([msgs[i].bias_dps for i in rows])
    np.testing.assert_allclose(zero.offset_dps, (raw - model).mean(axis=0), atol=1e-12)


def test_the_carried_zero_uses_one_estimate_for_both_models(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """A reload mid-heating with the same model but another estimator setting (τ × 1.0001:
    the estimator restarts, the next estimate is a fresh one with ΔT ≈ 0): b_old and b_new
    are taken at the same estimate, so an identical model carries the zero unchanged."""
    import dataclasses

    pipe, _ = _pipe(stream_calibration, [])
    for msg in run_frames(short_runs[1], FrameEncoder()):  # until well into the heating
        pipe.process(msg, 1.0e9)
        est, z = pipe.last_estimate, pipe.compensation.zero
        if (est is not None and abs(est.delta_t_c) > 0.5 and z is not None
                and z.status == ZeroStatus.DONE and msg.arbitration_id != TEMPERATURE_ID):
            break
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    assert pipe.last_estimate is not None and abs(pipe.last_estimate.delta_t_c) > 0.5
    before = zero.offset_dps
    est = dataclasses.replace(stream_calibration.estimator,
                              tau_s=stream_calibration.estimator.tau_s * 1.0001)
    pipe.set_calibration(dataclasses.replace(stream_calibration, estimator=est))
    assert zero.status == ZeroStatus.DONE and not zero.unverified
    np.testing.assert_allclose(zero.offset_dps, before, atol=1e-12)  # to rounding
