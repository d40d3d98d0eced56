"""The daemon's boot-time zero: the same corrected rates as offline evaluation (to
1e-9 °/s) with version-1 and version-2 calibrations, the offset equal to the mean
of the window computed by hand from the daemon's own messages, flags and state
message, a new power-on, another calibration, and a restart that keeps it."""

from __future__ import annotations

import json
import logging
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm import ConfigError
from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, Run, TemperatureSample
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration, ZeroConfig, ZeroStatus, features, removed_bias
from gyrotherm.daemon import Pipeline, parse_config
from streamkit import (
    RecordingSink,
    make_v2,
    offline_bias,
    restart_setup,
    run_daemon_in_process,
    run_frames,
)

ZERO = ZeroConfig(window_s=30.0, settle_s=20.0, max_std_dps=0.5, max_step_dps=0.05,
                  max_offset_dps=1.0, deadline_s=600.0)
PENDING = StatusFlags.ZERO_PENDING


def _stream(cal: Calibration | None, frames: list, zero: ZeroConfig = ZERO) -> tuple[
        Pipeline, RecordingSink]:
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal, zero=zero)  # type: ignore[arg-type]
    for msg in frames:
        pipe.process(msg, 1.0e9)
    return pipe, sink


def _offline(run: Run, cal: Calibration) -> tuple[np.ndarray, ZeroStatus, float]:
    rb = removed_bias(cal, features(run, cal.estimator), zero=ZERO)
    assert rb.zero is not None
    bias = np.column_stack([rb.bias[a][0] for a in "xyz"])
    return run_rates(run) - bias, rb.zero.status, rb.zero.done_s


def run_rates(run: Run) -> np.ndarray:
    return np.column_stack([run.rates_dps[a] for a in "xyz"])


@pytest.mark.parametrize("version", [1, 2])
def test_zero_matches_offline_and_the_hand_computed_window(
        short_runs: list[Run], stream_calibration: Calibration, version: int,
        caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="gyrotherm.daemon")
    cal = stream_calibration if version == 1 else make_v2(stream_calibration)
    run = short_runs[0].slice(0, 600)
    pipe, sink = _stream(cal, list(run_frames(run, FrameEncoder())))
    assert pipe.counters().drops == {}
    msgs = [decode_rate(p) for p in sink.rates]
    rates = np.array([m.rate_dps for m in msgs])
    want, status, done_s = _offline(run, cal)
    assert status == ZeroStatus.DONE
    np.testing.assert_allclose(rates, want, atol=1e-9)
    # by hand: 1 Hz rows, power-on at t0; the window opens at t0 + 20 s and the row at
    # t0 + 50 s closes it; z = mean(raw − bias) over the 30 rows in between, taken from
    # the daemon's own messages (bias = the model's only while pending)
    t = run.time_s - run.time_s[0]
    done = int(np.flatnonzero(t >= 50.0)[0])
    assert run.time_s[done] == done_s
    pending = np.array([bool(m.flags & PENDING) for m in msgs])
    assert pending[:done].all() and not pending[done:].any()
    window = (t >= 20.0) & (t < 50.0)
    raw = np.array([m.raw_rate_dps for m in msgs])
    model = np.array([m.bias_dps for m in msgs])
    z = (raw[window] - model[window]).mean(axis=0)
    np.testing.assert_allclose(model[done:] - z, want_model_bias(cal, run)[done:], atol=1e-9)
    states = [decode_state(p) for p in sink.states]
    last = states[-1].zero
    assert last is not None and last.status == ZeroStatus.DONE
    np.testing.assert_allclose(last.offset_dps, z, atol=1e-12)
    assert states[0].zero is not None and states[0].zero.status == ZeroStatus.PENDING
    assert abs(z[0]) > 1e-4  # a real offset was removed, not a zero of zeros
    said = [r.getMessage() for r in caplog.records if "boot-time zero" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("boot-time zero done at t = ")
    assert f"x {z[0]:+.5f}" in said[0]


def want_model_bias(cal: Calibration, run: Run) -> np.ndarray:
    rb = removed_bias(cal, features(run, cal.estimator))
    return np.column_stack([rb.bias[a][0] for a in "xyz"])


def test_power_on_after_a_silence_measures_a_new_zero(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """A second power-on (a 45-s sensor silence > power_on_gap_s 30 s, within the
    60-s time window) with 0.1 °/s more on every axis: pending again for 50 s, then
    z = the hand-computed mean of the second window, ≈ 0.1 °/s above the first."""
    run = short_runs[0].slice(0, 200)
    later = replace(run, time_s=run.time_s + run.time_s[-1] + 45.0,
                    rates_dps={a: v + 0.1 for a, v in run.rates_dps.items()})
    frames = list(run_frames(run, FrameEncoder())) + list(run_frames(later, FrameEncoder()))
    _, sink = _stream(stream_calibration, frames)
    msgs = [decode_rate(p) for p in sink.rates]
    assert len(msgs) == 400
    pending = np.array([bool(m.flags & PENDING) for m in msgs])
    assert pending[:50].all() and not pending[50:200].any()
    assert pending[200:250].all() and not pending[250:].any()
    t2 = later.time_s - later.time_s[0]
    window = 200 + np.flatnonzero((t2 >= 20.0) & (t2 < 50.0))
    raw = np.array([m.raw_rate_dps for m in msgs])
    model = np.array([m.bias_dps for m in msgs])
    z_hand = (raw[window] - model[window]).mean(axis=0)
    states = [decode_state(p) for p in sink.states]
    z_first = np.array(states[150].zero.offset_dps)  # type: ignore[union-attr]
    z_second = np.array(states[-1].zero.offset_dps)  # type: ignore[union-attr]
    np.testing.assert_allclose(z_second, z_hand, atol=1e-12)
    np.testing.assert_allclose(z_second - z_first, 0.1, atol=0.01)


def test_another_calibration_carries_the_zero_over_the_same_keeps_it(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """A reload never re-measures a zero that was done (the vehicle may be moving):
    z' = z + b_old − b_new at the current estimate, so the bias removed is continuous
    at the reload (b_new + z' = b_old + z) and the flags stay clean. A calibration
    loaded where there was none starts a zero that ends ZERO_UNVERIFIED."""
    run = short_runs[0].slice(0, 300)
    frames = list(run_frames(run, FrameEncoder()))
    pipe, sink = _stream(stream_calibration, frames[:200])
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    kept = zero.offset_dps
    pipe.set_calibration(Calibration.from_dict(stream_calibration.to_dict()))  # equal content
    assert zero.status == ZeroStatus.DONE and zero.offset_dps == kept
    assert not pipe.flags & PENDING
    last = decode_rate(sink.rates[-1])
    assert frames[199].arbitration_id == FrameEncoder().layout.rate.frame_id  # last: a rate
    v2 = make_v2(stream_calibration)
    pipe.set_calibration(v2)  # another model at the same estimate
    assert zero.status == ZeroStatus.DONE and zero.offset_dps != kept
    assert not pipe.flags & (PENDING | StatusFlags.ZERO_UNVERIFIED | StatusFlags.ZERO_FAILED)
    est = pipe.last_estimate
    assert est is not None
    b_old = stream_calibration.bias_at(est.temperature_c, est.delta_t_c).bias_dps
    np.testing.assert_allclose(np.array(last.bias_dps) - [b_old[a] for a in "xyz"], kept,
                               atol=1e-12)  # the message before: b_old + z
    pipe.process(frames[201], 1.0e9)  # the next rate frame, same estimate
    after = decode_rate(sink.rates[-1])
    np.testing.assert_allclose(after.bias_dps, last.bias_dps, atol=1e-12)
    assert not after.flags & (PENDING | StatusFlags.ZERO_UNVERIFIED)
    pipe.set_calibration(None)  # nothing removed without a calibration
    assert zero.status == ZeroStatus.OFF and not pipe.flags & (PENDING | StatusFlags.ZERO_FAILED)
    pipe.set_calibration(stream_calibration)  # none before: a zero the daemon cannot trust
    assert zero.status == ZeroStatus.PENDING and pipe.flags & PENDING
    for msg in frames[202:]:
        pipe.process(msg, 1.0e9)
    assert zero.status == ZeroStatus.DONE and zero.unverified
    assert pipe.flags & StatusFlags.ZERO_UNVERIFIED
    assert decode_state(sink.states[-1]).flags & StatusFlags.ZERO_UNVERIFIED


def test_no_rest_window_before_the_deadline_fails(
        short_runs: list[Run], stream_calibration: Calibration,
        caplog: pytest.LogCaptureFixture) -> None:
    run = short_runs[0].slice(0, 200)
    rng = np.random.default_rng(5)
    shaken = replace(run, rates_dps={a: v + rng.normal(0.0, 2.0, len(v))
                                     for a, v in run.rates_dps.items()})
    cfg = ZeroConfig(window_s=30.0, settle_s=20.0, deadline_s=120.0)
    _, sink = _stream(stream_calibration, list(run_frames(shaken, FrameEncoder())), cfg)
    msgs = [decode_rate(p) for p in sink.rates]
    t = shaken.time_s - shaken.time_s[0]
    failed = np.array([bool(m.flags & StatusFlags.ZERO_FAILED) for m in msgs])
    assert not failed[t <= 120.0].any() and failed[t > 120.0].all()
    assert decode_state(sink.states[-1]).zero.status == ZeroStatus.FAILED  # type: ignore[union-attr]
    assert "boot-time zero failed: no window at rest within deadline_s = 120 s" in caplog.text
    # nothing removed beyond the model's bias, before or after the failure
    np.testing.assert_allclose([m.bias_dps for m in msgs],
                               want_model_bias(stream_calibration, shaken), atol=1e-9)


def test_restart_keeps_a_zero_that_was_done(
        tmp_path: Path, short_runs: list[Run], stream_calibration: Calibration) -> None:
    """Version-1 calibration, state_dir: stopped after the zero, started again while
    the gyro keeps running: no new rest window is needed, and the corrected rates
    of both daemons equal offline evaluation of the whole run from power-on."""
    cal_path = stream_calibration.save(tmp_path / "cal.json")
    run = short_runs[0].slice(0, 300)
    frames, channel, port, cfg = restart_setup(tmp_path, cal_path, run, "zero",
                                               zero={"window_s": 30.0, "settle_s": 20.0})
    cut = 120
    r1, s1, _ = run_daemon_in_process(cfg, tmp_path, frames[:2 * cut], channel, port, cut)
    saved = json.loads((tmp_path / "state" / "car.imu0.effects-state.json").read_text())
    assert saved["zero"]["status"] == "done"
    r2, s2, _ = run_daemon_in_process(cfg, tmp_path, frames[2 * cut:], channel, port,
                                      len(run) - cut)
    assert not any(r.flags & PENDING for r in r2)
    assert s2[0].zero is not None and s2[0].zero.status == ZeroStatus.DONE
    assert s2[0].zero.offset_dps == tuple(saved["zero"]["offset_dps"])
    # the estimator starts again at the restart (its state is not kept): the reference
    # is the offline model on the daemons' own estimates, plus z from the closing row
    states = s1 + s2
    ref = offline_bias(stream_calibration, np.array([s.sensor_time_s for s in states]),
                       np.array([s.temperature_c for s in states]),
                       np.array([s.delta_t_c for s in states]))
    z = np.array(s2[0].zero.offset_dps)
    t = run.time_s - run.time_s[0]
    removed = np.column_stack([ref[a] for a in "xyz"]) + np.where((t >= 50.0)[:, None], z, 0.0)
    np.testing.assert_allclose(np.array([r.rate_dps for r in r1 + r2]),
                               run_rates(run) - removed, atol=1e-9)
    assert [bool(r.flags & PENDING) for r in r1] == list(t[:cut] < 50.0)


def test_zero_table_in_the_daemon_config() -> None:
    base = {"vehicle": "v", "sensor": "s", "can": {"interface": "virtual", "channel": "c"},
            "zenoh": {"listen": []}}
    assert parse_config(base).zero is None
    assert parse_config({**base, "zero": {}}).zero == ZeroConfig()
    assert parse_config({**base, "zero": {"window_s": 60}}).zero == ZeroConfig(window_s=60.0)
    with pytest.raises(ConfigError, match=r"gyro.toml: \[zero\]: zero.max_step_dps = -1"):
        parse_config({**base, "zero": {"max_step_dps": -1}}, source="gyro.toml")


def test_a_sensor_fault_throughout_still_ends_in_zero_failed(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """Every temperature frame reports a fault (SENSOR_FAULT on every rate frame): no
    window can open, and the zero fails at its deadline instead of pending forever."""
    run = short_runs[0].slice(0, 200)
    enc = FrameEncoder()
    frames = []
    for i, t in enumerate(run.time_s.tolist()):
        frames.append(enc.encode_temperature(TemperatureSample(t, float(run.temperature_c[i]),
                                                               status=1)))
        frames.append(enc.encode_rate(RateSample(t, *(float(run.rates_dps[a][i])
                                                      for a in "xyz"))))
    cfg = ZeroConfig(window_s=30.0, settle_s=20.0, deadline_s=120.0)
    _, sink = _stream(stream_calibration, frames, cfg)
    msgs = [decode_rate(p) for p in sink.rates]
    t = run.time_s - run.time_s[0]
    failed = np.array([bool(m.flags & StatusFlags.ZERO_FAILED) for m in msgs])
    assert all(m.flags & StatusFlags.SENSOR_FAULT for m in msgs[1:])
    assert not failed[t <= 120.0].any() and failed[t > 120.0].all()


def test_a_temperature_dropout_while_rates_flow_is_not_a_power_on(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """40 s without temperature frames (> power_on_gap_s 30 s) while the rate frames
    keep coming: the zero stays done and the power-on time is unchanged."""
    run = short_runs[0].slice(0, 300)
    frames = [m for m in run_frames(run, FrameEncoder())
              if not (m.arbitration_id == FrameEncoder().layout.temperature.frame_id
                      and 150.0 <= m.timestamp - run.time_s[0] < 190.0)]
    pipe, sink = _stream(stream_calibration, frames)
    assert pipe.compensation.power_on_s == run.time_s[0]
    msgs = [decode_rate(p) for p in sink.rates]
    assert not any(m.flags & PENDING for m in msgs[60:])
    zero = pipe.compensation.zero
    assert zero is not None and zero.status == ZeroStatus.DONE
    assert zero.done_s == run.time_s[50]  # the one zero, taken at 50 s


def test_held_frames_slower_than_stale_after_are_not_stale(
        short_runs: list[Run], stream_calibration: Calibration) -> None:
    """A calibration whose sensor refreshes every 8 s (update_period_s) with
    stale_after_s = 5 s, frames every second repeating the held reading: frames keep
    arriving, so nothing is flagged stale after the start, and the zero is taken."""
    run = short_runs[0].slice(0, 200)
    est = replace(stream_calibration.estimator, update_period_s=8.0, stale_after_s=5.0)
    cal = replace(stream_calibration, estimator=est)
    _, sink = _stream(cal, list(run_frames(run, FrameEncoder())))
    msgs = [decode_rate(p) for p in sink.rates]
    assert not any(m.flags & StatusFlags.TEMPERATURE_STALE for m in msgs[1:])
    assert decode_state(sink.states[-1]).zero.status == ZeroStatus.DONE  # type: ignore[union-attr]


def test_saved_state_without_or_with_a_broken_zero_still_restores_the_effects(
        tmp_path: Path) -> None:
    from gyrotherm.daemon._effects_store import load

    base = {"schema": "gyrotherm.effects-state", "version": 1, "vehicle": "v", "sensor": "s",
            "calibration_id": "c", "power_on_s": 10.0, "time_s": 20.0,
            "compensator": {"x": {}}}
    path = tmp_path / "state.json"
    for zero in (None, {"status": "done", "offset_dps": [1, 2]},
                 {"status": "maybe", "offset_dps": [0, 0, 0]}):
        path.write_text(json.dumps(base if zero is None else {**base, "zero": zero}))
        saved = load(path)
        assert saved is not None and saved.snapshot.power_on_s == 10.0
        assert saved.snapshot.state == {"x": {}} and saved.snapshot.zero is None
    good = {"status": "done", "offset_dps": [0.5, -0.25, 0.0], "done_s": 15.0}
    path.write_text(json.dumps({**base, "zero": good}))
    saved = load(path)
    assert saved is not None and saved.snapshot.zero == {  # an older file: the defaults
        **good, "start_s": None, "trusted": True, "unverified": False}
