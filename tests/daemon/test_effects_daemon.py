"""The daemon runs version-2 calibrations (effects): its corrected rates equal the
offline compensator on the same estimator output (to 1e-9 °/s) straight through, across
a SIGHUP re-reading the same file and across a restart with persisted state; power-on,
T_ON_CLAMPED and the SIGHUP rule for another calibration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrotherm import ConfigError
from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, Run, TemperatureSample
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration
from gyrotherm.daemon import Daemon, Pipeline, parse_config
from gyrotherm.daemon._effects_store import EffectsKeeper
from streamkit import (
    ALL_EFFECTS,
    RecordingSink,
    assert_offline_compensation,
    make_v2,
    offline_bias,
    run_frames,
)


@pytest.fixture(scope="module")
def v2(stream_calibration: Calibration) -> Calibration:
    cal = make_v2(stream_calibration)
    assert cal.version == 2 and set(cal.effect_names("x")) == set(ALL_EFFECTS)
    return cal


def _pipe(cal: Calibration | None, sink: RecordingSink, **kw: float) -> Pipeline:
    return Pipeline(FrameDecoder(), sink, calibration=cal, **kw)  # type: ignore[arg-type]


def _reference(v2: Calibration, sink: RecordingSink) -> dict[str, np.ndarray]:
    """The offline compensator on the daemon's own estimator output (its state messages)."""
    states = [decode_state(p) for p in sink.states]
    return offline_bias(v2, np.array([s.sensor_time_s for s in states]),
                        np.array([s.temperature_c for s in states]),
                        np.array([s.delta_t_c for s in states]))


def test_v2_rates_equal_the_offline_compensator(short_runs: list[Run], v2: Calibration) -> None:
    run = short_runs[0]
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    for msg in run_frames(run, FrameEncoder()):
        pipe.process(msg, 1.0e9)
    assert pipe.counters().drops == {}
    offline = assert_offline_compensation([decode_rate(p).rate_dps for p in sink.rates], run, v2)
    # the effects matter here: the polynomial alone is far off
    assert np.max(np.abs(_reference(v2, sink)["x"] - v2.base_series(
        "x", offline.temperature_c, offline.delta_t_c))) > 1e-3
    last = decode_state(sink.states[-1])
    assert last.effects["x"].t_on_s == run.time_s[-1] - run.time_s[0]
    kernel = pipe.compensation.compensator.kernels["x"]  # type: ignore[union-attr]
    assert last.effects["x"].structure_temperature_c == kernel.state.structure_temperature_c
    assert kernel.state.samples == len(run)  # stepped once per temperature frame


def test_sighup_with_the_same_file_continues_the_state(
    short_runs: list[Run], v2: Calibration, tmp_path: Path
) -> None:
    """The real reload path (Daemon._do_reload: read the file, set_calibration) twice
    mid-run: the state continues and no estimate is stepped twice."""
    path = v2.save(tmp_path / "v2.json")
    run = short_runs[1]
    daemon = Daemon(parse_config({"vehicle": "v", "sensor": "s", "calibration": str(path),
                                  "can": {"interface": "virtual", "channel": "eff"},
                                  "zenoh": {"listen": []}}))
    sink = RecordingSink()
    pipe = _pipe(daemon._calibration, sink)
    frames = list(run_frames(run, FrameEncoder()))
    for k, msg in enumerate(frames):
        if k in (700, 701, 2000):
            daemon._do_reload(pipe)
        pipe.process(msg, 1.0e9)
    assert daemon.reloads == 3 and daemon.reload_failures == 0
    assert pipe.compensation.compensator.kernels["x"].state.samples == len(run)  # type: ignore[union-attr]
    assert_offline_compensation([decode_rate(p).rate_dps for p in sink.rates], run, v2)


@pytest.mark.parametrize("cut", [900, 1701])
def test_restart_with_persisted_state_continues(
    short_runs: list[Run], v2: Calibration, tmp_path: Path, cut: int
) -> None:
    """Daemon A runs to ``cut``, saves; daemon B (new pipeline, new estimator) restores
    and goes on. Reference: the offline compensator over A's and B's estimator outputs
    as one series from power-on, i.e. exactly as if the kernel had never stopped."""
    run = short_runs[2].slice(0, 2400)
    frames = list(run_frames(run, FrameEncoder()))
    keeper = EffectsKeeper(tmp_path, "v", "s")
    sink = RecordingSink()
    a = _pipe(v2, sink)
    for msg in frames[:2 * cut]:
        a.process(msg, 1.0e9)
    keeper.save(a.compensation, "cal-1", 0.0, force=True)
    saved = json.loads(keeper.path.read_text())  # type: ignore[union-attr]
    assert saved["calibration_id"] == "cal-1" and saved["power_on_s"] == run.time_s[0]
    b = _pipe(v2, sink)
    EffectsKeeper(tmp_path, "v", "s").restore(b.compensation, "cal-1")
    for msg in frames[2 * cut:]:
        b.process(msg, 1.0e9)
    rates = np.array([decode_rate(p).rate_dps for p in sink.rates])
    ref = _reference(v2, sink)
    for j, axis in enumerate("xyz"):
        np.testing.assert_allclose(rates[:, j], run.rates_dps[axis] - ref[axis], atol=1e-9)
    assert decode_state(sink.states[cut]).effects["x"].t_on_s == run.time_s[cut] - run.time_s[0]
    # negative control: without the saved state B replays the warm-up from t_on = 0
    fresh_sink = RecordingSink()
    c = _pipe(v2, fresh_sink)
    for msg in frames[2 * cut:]:
        c.process(msg, 1.0e9)
    assert decode_state(fresh_sink.states[0]).effects["x"].t_on_s == 0.0
    fresh = np.array([decode_rate(p).rate_dps for p in fresh_sink.rates])
    assert np.max(np.abs(fresh[:, 0] - rates[cut:, 0])) > 1e-3


def _save_after(v2: Calibration, tmp_path: Path, n: int) -> EffectsKeeper:
    enc = FrameEncoder()
    pipe = _pipe(v2, RecordingSink())
    for k in range(n):
        pipe.process(enc.encode_temperature(TemperatureSample(100.0 + k, 20.0)), 0.0)
    keeper = EffectsKeeper(tmp_path, "v", "s")
    keeper.save(pipe.compensation, "cal-1", 0.0, force=True)
    return keeper


@pytest.mark.parametrize(("cal_id", "first_s", "t_on_s"), [
    ("cal-1", 100.0 + 9 + 30.0, 39.0),   # continues within the 30 s gap: restored
    ("cal-1", 100.0 + 9 + 30.5, 0.0),    # a longer silence: power-on
    ("cal-1", 100.0 + 8, 0.0),           # earlier than the saved time: another clock
    ("cal-2", 100.0 + 10, 0.0),          # another calibration: power-on
])
def test_restore_only_for_the_same_calibration_continuing_in_time(
    v2: Calibration, tmp_path: Path, cal_id: str, first_s: float, t_on_s: float
) -> None:
    _save_after(v2, tmp_path, 10)  # power-on at 100 s, last step at 109 s
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    EffectsKeeper(tmp_path, "v", "s").restore(pipe.compensation, cal_id)
    pipe.process(FrameEncoder().encode_temperature(TemperatureSample(first_s, 20.0)), 0.0)
    assert decode_state(sink.states[0]).effects["x"].t_on_s == t_on_s


def test_a_broken_state_file_is_ignored(v2: Calibration, tmp_path: Path) -> None:
    keeper = _save_after(v2, tmp_path, 3)
    keeper.path.write_text('{"schema": "gyrotherm.effects-state", "version": 1}')  # type: ignore[union-attr]
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    EffectsKeeper(tmp_path, "v", "s").restore(pipe.compensation, "cal-1")
    pipe.process(FrameEncoder().encode_temperature(TemperatureSample(103.0, 20.0)), 0.0)
    assert decode_state(sink.states[0]).effects["x"].t_on_s == 0.0


def test_power_on_after_a_silence_and_after_a_time_base_change(v2: Calibration) -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = _pipe(v2, sink, power_on_gap_s=10.0)
    times = [5.0, 6.0, 16.0, 26.5, 27.5]  # 10 s: same power-on; 10.5 s: a new one
    for t in times:
        pipe.process(enc.encode_temperature(TemperatureSample(t, 20.0)), 0.0)
    assert [decode_state(p).effects["x"].t_on_s for p in sink.states] == [
        0.0, 1.0, 11.0, 0.0, 1.0]
    # a time base change (5 consecutive frames far back) is a power-on too
    for t in (1.0, 2.0, 3.0, 4.0, 5.0, 6.0):
        pipe.process(enc.encode_temperature(TemperatureSample(t - 1e6, 20.0)), 0.0)
    assert pipe.time_base_changes["temperature"] == 1
    assert [decode_state(p).effects["x"].t_on_s for p in sink.states[-2:]] == [0.0, 1.0]


def test_t_on_beyond_the_calibrated_runs_sets_t_on_clamped(
    stream_calibration: Calibration
) -> None:
    cal = make_v2(stream_calibration, t_on_max_s=3.0)
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = _pipe(cal, sink)
    for k in range(6):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0)), 0.0)
        pipe.process(enc.encode_rate(RateSample(k + 0.5, 0.1, 0.2, 0.3)), 0.0)
    flags = [bool(decode_rate(p).flags & StatusFlags.T_ON_CLAMPED) for p in sink.rates]
    assert flags == [False, False, False, False, True, True]
    assert decode_state(sink.states[-1]).flags & StatusFlags.T_ON_CLAMPED


def test_sighup_with_another_model_of_the_same_kinds_takes_the_state_over(
    short_runs: list[Run], v2: Calibration, stream_calibration: Calibration
) -> None:
    """Same effect kinds, other coefficients: the state continues (one series from
    power-on); the bias after the swap is the new model's on that continued state."""
    other = make_v2(stream_calibration, scale=1.5)
    run = short_runs[0].slice(0, 1500)
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    frames = list(run_frames(run, FrameEncoder()))
    for k, msg in enumerate(frames):
        if k == 1000:
            pipe.set_calibration(other)
        pipe.process(msg, 1.0e9)
    rates = np.array([decode_rate(p).rate_dps for p in sink.rates])
    old, new = _reference(v2, sink), _reference(other, sink)  # both from power-on
    for j, axis in enumerate("xyz"):
        np.testing.assert_allclose(rates[:500, j], run.rates_dps[axis][:500] - old[axis][:500],
                                   atol=1e-9)
        np.testing.assert_allclose(rates[500:, j], run.rates_dps[axis][500:] - new[axis][500:],
                                   atol=1e-9)


def test_sighup_with_other_effect_kinds_starts_their_state_at_the_estimate(
    short_runs: list[Run], v2: Calibration, stream_calibration: Calibration
) -> None:
    other = make_v2(stream_calibration, y_effects=False)
    run = short_runs[0].slice(0, 1500)
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    frames = list(run_frames(run, FrameEncoder()))
    for k, msg in enumerate(frames):
        if k == 1000:
            pipe.set_calibration(other)
        pipe.process(msg, 1.0e9)
    states = [decode_state(p) for p in sink.states]
    # stepped once at the current estimate (frame 499's): T_s = T there, h = 0
    swap = states[499]
    kernel = pipe.compensation.compensator.kernels  # type: ignore[union-attr]
    assert kernel["x"].state.samples == len(run) - 499
    rates = np.array([decode_rate(p).rate_dps for p in sink.rates])
    tail = states[499:]
    t = np.array([s.sensor_time_s for s in tail])
    # a fresh compensator from the estimate at the swap; t_on still from the power-on
    ref = other.compensator().series(t, np.array([s.temperature_c for s in tail]),
                                     np.array([s.delta_t_c for s in tail]), t - run.time_s[0])
    assert states[500].effects["x"].t_on_s == run.time_s[500] - run.time_s[0]
    assert states[500].effects["x"].hysteresis_direction in (-1, 0, 1)
    assert swap.effects["x"].t_on_s == run.time_s[499] - run.time_s[0]
    for j, axis in enumerate("xyz"):
        np.testing.assert_allclose(rates[500:, j], run.rates_dps[axis][500:]
                                   - ref.bias_dps[axis][1:], atol=1e-9)
    # and it differs from a taken-over state (the lag restarted at T)
    kept = _reference(other, sink)["x"][500:]
    assert np.max(np.abs(kept - ref.bias_dps["x"][1:])) > 1e-6


def _cfg(**top: object) -> dict[str, object]:
    return {"vehicle": "v", "sensor": "s", "can": {"interface": "virtual", "channel": "c"},
            "zenoh": {"listen": []}, **top}


def test_config_state_dir_and_power_on_gap(tmp_path: Path) -> None:
    cfg = parse_config(_cfg(state_dir="state", power_on_gap_s=12), source="g.toml",
                       base_dir=tmp_path)
    assert cfg.state_dir == tmp_path / "state" and cfg.power_on_gap_s == 12.0
    default = parse_config(_cfg())
    assert default.state_dir is None and default.power_on_gap_s == 30.0
    assert EffectsKeeper(default.state_dir, "v", "s").path is None  # no persistence
    for bad, pattern in [({"power_on_gap_s": 0.5}, r"g\.toml: power_on_gap_s = 0\.5 is outside"),
                         ({"power_on_gap_s": "30"}, r"g\.toml: key 'power_on_gap_s' must be"),
                         ({"state_dir": 3}, r"g\.toml: key 'state_dir' must be str, got 3"),
                         ({"state_dir": " "}, r"g\.toml: state_dir = ' ': must name a dir")]:
        with pytest.raises(ConfigError, match=pattern):
            parse_config(_cfg(**bad), source="g.toml")


def test_the_predict_only_tick_steps_the_compensator_once(v2: Calibration) -> None:
    """Temperature frames stop, rates go on: tick() predicts to the latest rate stamp
    and steps the kernels there (t_on included); re-setting the same calibration
    re-evaluates without stepping; rate frames never step."""
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = _pipe(v2, sink)
    for k in range(10):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0 + 0.1 * k)), 0.0)
    kernels = pipe.compensation.compensator.kernels  # type: ignore[union-attr]
    for k in range(50):
        pipe.process(enc.encode_rate(RateSample(9.0 + 0.2 * k, 0.0, 0.0, 0.0)), 0.0)
    assert kernels["x"].state.samples == 10  # rate frames do not step
    pipe.tick()  # 18.8 s: 9.8 s after the last temperature frame (> stale_after_s 5 s)
    assert kernels["x"].state.samples == 11 and kernels["x"].state.time_s == 18.8
    assert pipe.compensation.t_on_s == 18.8
    est = pipe.last_estimate
    assert est is not None and est.time_s == 18.8
    want = v2.compensator()
    for k in range(10):
        want.step(float(k), *_estimate_at(sink, k))
    bias = want.step(18.8, est.temperature_c, est.delta_t_c, 18.8).bias_dps
    pipe.set_calibration(v2)
    assert kernels["x"].state.samples == 11
    pipe.process(enc.encode_rate(RateSample(19.0, 0.0, 0.0, 0.0)), 0.0)
    got = decode_rate(sink.rates[-1]).bias_dps
    assert got == (bias["x"], bias["y"], bias["z"])


def _estimate_at(sink: RecordingSink, k: int) -> tuple[float, float, float]:
    s = decode_state(sink.states[k])
    return s.temperature_c, s.delta_t_c, s.sensor_time_s
