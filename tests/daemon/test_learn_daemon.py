"""The daemon's [learn] mode end to end on simulated power-ons (issue 21 item 2): nothing
adopted before the gates pass (it compensates with what it has: nothing), adoption after
enough warm-ups from spread ambients (five, ``min_warmups = 5``), the swap without a
dropped frame, the adopted calibration's bias error against the simulator's truth below
the uncompensated one on held-out power-ons (with the boot-time zero [learn] requires),
and a restart that loads it. Also the [learn] table's validation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyrotherm import ConfigError, __version__
from gyrotherm.codecs import Run
from gyrotherm.compensation import ZeroConfig, read_calibration
from gyrotherm.daemon import parse_config, parse_vehicle_config
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.sim._life import power_on
from learnkit import boot, frames, life_of

AMBIENTS_C = (-8.0, 3.0, 14.0, 27.0, 38.0)
FIVE = LearnConfig(min_warmups=5)
ZERO = ZeroConfig(window_s=30.0, settle_s=30.0)


def _life() -> list[Run]:
    """Five power-ons at rest for 600 s, then driving off (60 s of turning)."""
    return [power_on(a, warmup_s=600.0, motion_s=60.0, seed=500 + k, name=f"p{k}")
            for k, a in enumerate(AMBIENTS_C)]


def test_learns_adopts_without_dropping_a_frame_and_beats_no_compensation(
        tmp_path: Path) -> None:
    runs = _life()
    boots = life_of(tmp_path, runs, config=FIVE, zero=ZERO)
    # power-ons 1-4: learning, nothing adopted; with no calibration nothing is removed
    for k, b in enumerate(boots[:4]):
        last = b.states()[-1].learn
        need = 4 - k
        assert last is not None and last.warmups_used == k + 1
        assert last.need_warmups == need and math.isnan(last.adopted_time_s)
        assert last.status.startswith(f"learning: need {need} more warm-up")
        assert b.pipeline.calibration is None
        assert np.all(np.array([s.bias_dps for s in b.states()]) == 0.0)
    # 5th: the warm-up ends when the vehicle drives off, decide adopts, swapped in place
    fifth = boots[4]
    assert fifth.pipeline.calibration is not None and fifth.calibration_id
    assert len(fifth.sink.rates) == len(runs[4].time_s)  # every rate frame published
    assert fifth.pipeline.counters().drops == {}
    learn = fifth.states()[-1].learn
    assert learn is not None and learn.status.startswith("adopted at ")
    assert learn.candidate_rms_dps < learn.current_rms_dps
    learnt = tmp_path / "car.imu0.learnt-calibration.json"
    cal, cid = read_calibration(learnt)
    assert cid == fifth.calibration_id
    prov = cal.provenance
    assert prov["learnt_for"] == {"vehicle": "car", "sensor": "imu0"}
    assert [p["name"] for p in prov["power_ons"]] == [w.name for w in
                                                      fifth.learner.record.learn.warmups]
    assert prov["coverage_c"][0] < AMBIENTS_C[0] + 1 and prov["coverage_c"][1] > AMBIENTS_C[4]
    assert prov["validation"]["adopt"] and prov["margin_frac"] == LearnConfig().margin_frac
    assert prov["gyrotherm_version"] == __version__ and prov["replaces"] == "none"

    # held-out power-ons after a restart: the learnt calibration is loaded and, with the
    # boot-time zero, removes the simulator's true bias far better than nothing does
    for ambient_c, seed in ((0.0, 998), (20.0, 999), (33.0, 997)):
        held_out = power_on(ambient_c, warmup_s=600.0, seed=seed, name="held-out")
        b = boot(tmp_path, config=FIVE, zero=ZERO)
        assert b.calibration_id == cid and b.pipeline.calibration == cal
        b.feed(frames(held_out))
        b.stop()
        states = b.states()
        assert len(states) == len(held_out.time_s)
        bias = np.array([s.bias_dps for s in states])
        late = held_out.time_s >= 60.0  # the estimator converged, the zero taken
        for i, axis in enumerate("xyz"):
            truth = held_out.true_bias_dps[axis][late]
            err = float(np.sqrt(np.mean((bias[late, i] - truth) ** 2)))
            raw = float(np.sqrt(np.mean(truth ** 2)))
            assert err < 0.6 * raw, (ambient_c, axis, err, raw)


def test_motion_ends_the_warm_up_and_nothing_after_it_is_learnt(tmp_path: Path) -> None:
    run = power_on(10.0, warmup_s=300.0, motion_s=300.0, seed=7, name="drive")
    (b,) = life_of(tmp_path, [run])
    (w,) = b.learner.record.learn.warmups
    # rows from SETTLE_S (10 s) up to the last whole rest block before the turning starts
    assert w.n <= (300.0 - 10.0) * 10 + 1 and w.n >= (300.0 - 10.0 - 10.0) * 10
    assert b.learner.record.rejected == {}


def test_learn_table_validation_names_the_key_and_value(tmp_path: Path) -> None:
    base = {"vehicle": "car", "sensor": "imu0", "state_dir": str(tmp_path), "zero": {},
            "can": {"interface": "virtual", "channel": "x"}}
    cfg = parse_config({**base, "learn": {"margin_frac": 0.2}})
    assert cfg.learn == LearnConfig(margin_frac=0.2)
    assert parse_config({**base, "learn": {"enabled": False}}).learn is None
    assert parse_config(base).learn is None
    for table, match in [({"margin_frac": 1.5}, r"\[learn\]: learn.margin_frac = 1.5 is outside"),
                         ({"min_warmups": 2}, r"learn.min_warmups = 2 is outside \[3, 256\]"),
                         ({"min_warmups": 3.5}, r"learn.min_warmups = 3.5: expected an integer"),
                         ({"warmup_window_s": 5000}, r"warmup_window_s = 5000 is outside"),
                         ({"min_rest_s": 1000, "warmup_window_s": 600},
                          r"min_rest_s = 1000 s cannot fit"),
                         ({"max_std": 1}, r"unknown key\(s\) \['max_std'\]"),
                         ({"enabled": "yes"}, r"enabled = 'yes': expected true or false")]:
        with pytest.raises(ConfigError, match=match):
            parse_config({**base, "learn": table})
    no_dir = {k: v for k, v in base.items() if k != "state_dir"}
    with pytest.raises(ConfigError, match=r"\[learn\] needs state_dir"):
        parse_config({**no_dir, "learn": {}})
    no_zero = {k: v for k, v in base.items() if k != "zero"}
    with pytest.raises(ConfigError, match=r"\[learn\] needs \[zero\]"):
        parse_config({**no_zero, "learn": {}})


def test_learn_per_imu_overrides_the_shared_table(tmp_path: Path) -> None:
    doc = {"vehicle": "car", "state_dir": str(tmp_path), "learn": {"min_warmups": 5},
           "zero": {},
           "can": {"interface": "virtual", "channel": "x"},
           "imu": [{"sensor": "imu0"},
                   {"sensor": "imu1", "learn": {"enabled": False},
                    "signals": {"rate_frame_id": 0x122, "temperature_frame_id": 0x123}},
                   {"sensor": "imu2", "learn": {"margin_frac": 0.3},
                    "signals": {"rate_frame_id": 0x124, "temperature_frame_id": 0x125}}]}
    v = parse_vehicle_config(doc)
    assert [c.learn for c in v.imus] == [LearnConfig(min_warmups=5), None,
                                         LearnConfig(min_warmups=5, margin_frac=0.3)]


def test_learning_state_file_is_bounded_statistics(tmp_path: Path) -> None:
    """Memory and disk hold sufficient statistics, never rows: the state file's size does
    not grow with the warm-up's length."""
    short = power_on(5.0, warmup_s=200.0, seed=1, name="s")
    long = power_on(5.0, warmup_s=1200.0, seed=1, name="l")
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    life_of(a, [short])
    life_of(b, [long])
    doc_a = json.loads((a / "car.imu0.learn-state.json").read_text())
    doc_b = json.loads((b / "car.imu0.learn-state.json").read_text())
    assert doc_a["learn"]["warmups"][0]["n"] < 2000 < 8000 < doc_b["learn"]["warmups"][0]["n"]
    size_a, size_b = len(json.dumps(doc_a["learn"])), len(json.dumps(doc_b["learn"]))
    assert abs(size_a - size_b) < 100 and size_b < 4000


def test_status_never_shows_an_older_decisions_reasons(tmp_path: Path) -> None:
    """A warm-up was just added and the worker has not decided on it yet: the status is
    'validating', not the previous decision's reasons (found by the whole-daemon test,
    where the decision runs on a worker thread)."""
    from gyrotherm.compensation import features
    from gyrotherm.compensation._learn import WarmupStats, decide
    from gyrotherm.compensation._learnstate import LearnState
    from gyrotherm.daemon._learn_store import LearnRecord
    from gyrotherm.daemon._learner import progress
    from gyrotherm.sim._life import life
    from learnkit import CONFIG, EST

    stats = [WarmupStats.from_features(features(r, EST)) for r in life(4, seed=5)]
    state = LearnState(("x", "y", "z"))
    for w in stats[:3]:
        state.add(w)
    record = LearnRecord("car", "imu0", state,
                         decision=decide(stats[:3], None, ("x", "y", "z")).to_dict())
    config = LearnConfig(min_warmups=3, min_rest_s=CONFIG.min_rest_s,
                         warmup_window_s=CONFIG.warmup_window_s, min_span_c=1.0)
    before = progress(record, config, adopted=False).status
    assert before == f"learning: {record.decision['reasons'][-1]}"  # type: ignore[index]
    state.add(stats[3])  # the fourth warm-up, not decided on yet
    assert progress(record, config, adopted=False).status == "learning: validating"
