"""Streaming and persisted learning state (compensation/_learnstate.py): the row-by-row
accumulator equals the batch statistics; the state round-trips through JSON, stays
bounded, and refuses corrupt or foreign documents naming the field."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from gyrotherm import CalibrationError
from gyrotherm.compensation import features
from gyrotherm.compensation._learn import WarmupStats, slopes
from gyrotherm.compensation._learnstate import MAX_POWER_ONS, LearnState, WarmupAccumulator
from gyrotherm.compensation._rest import rest_of_run
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim._life import LIFE_GYRO, life, power_on

EST = EstimatorConfig(tau_s=LIFE_GYRO.tau_s)
AXES = ("x", "y", "z")


def _streamed(f, name: str) -> WarmupStats | None:
    acc = WarmupAccumulator(name, AXES)
    rest = np.ones(len(f.time_s), dtype=bool) if f.rest is None else f.rest
    for i in range(len(f.time_s)):
        acc.add(float(f.time_s[i]), float(f.temperature_c[i]), float(f.delta_t_c[i]),
                [float(f.rates_dps[a][i]) for a in AXES], at_rest=bool(rest[i]))
    return acc.stats()


def test_streamed_warmup_equals_the_batch_statistics() -> None:
    run = power_on(12.0, warmup_s=400.0, motion_s=200.0, seed=41, name="p")
    f = replace(features(run, EST), rest=rest_of_run(run).rest)
    f.temperature_c[500] = np.nan  # a lost reading: both leave the row (and its pair) out
    batch = WarmupStats.from_features(f)
    streamed = _streamed(f, f.name)
    assert streamed is not None and streamed.n == batch.n and streamed.ndd == batch.ndd
    for key in ("sz", "szz"):
        np.testing.assert_allclose(getattr(streamed, key), getattr(batch, key), rtol=1e-9)
    for a in AXES:
        np.testing.assert_allclose(streamed.szy[a], batch.szy[a], rtol=1e-9, atol=1e-12)
        for key in ("sy", "syy", "sdd"):
            assert getattr(streamed, key)[a] == pytest.approx(getattr(batch, key)[a],
                                                              rel=1e-9, abs=1e-12)
    assert streamed.t_range_c == batch.t_range_c and streamed.start_c == batch.start_c


def test_a_warmup_too_short_gives_nothing() -> None:
    f = features(power_on(20.0, warmup_s=600.0, seed=42), EST)
    rest = f.time_s < 12.0  # moved off 2 s after the settling time
    assert _streamed(replace(f, rest=rest), "short") is None


def test_state_round_trips_through_json_and_stays_bounded() -> None:
    stats = [WarmupStats.from_features(features(r, EST)) for r in life(4, seed=43)]
    state = LearnState(AXES, list(stats))
    back = LearnState.from_dict(json.loads(json.dumps(state.to_dict())))
    assert back.warmups == stats
    np.testing.assert_array_equal(slopes(back.warmups, "x")[0], slopes(stats, "x")[0])
    for k in range(MAX_POWER_ONS + 5):
        state.add(replace(stats[k % 4], name=f"p{k}"))
    assert len(state.warmups) == MAX_POWER_ONS
    assert state.warmups[0].name == "p5"  # the 4 first and p0…p4 dropped: oldest first


@pytest.mark.parametrize(("edit", "needle"), [
    (lambda d: d.update(version=3), "field 'version': expected learning state version 2"),
    (lambda d: d.update(version=1), "version 1 keeps 4 basis terms per warm-up"),
    (lambda d: d.update(axes=["x", "q"]), "field 'axes'"),
    (lambda d: d["warmups"][1]["szz"].pop(), "field 'warmups[1].szz': expected a list of 36"),
    (lambda d: d["warmups"][0]["sy"].update(x=float("nan")), "'warmups[0].sy.x': not a finite"),
    (lambda d: d["warmups"][0].update(n=-3), "'warmups[0].n': expected a count"),
    (lambda d: d["warmups"][0].update(n=12), "12 rows, fewer than the 60"),
    (lambda d: d["warmups"][2]["szy"].pop("z"), "'warmups[2].szy': expected the axes"),
    (lambda d: d.update(warmups=[d["warmups"][0]] * (MAX_POWER_ONS + 1)),
     f"a list of at most {MAX_POWER_ONS}"),
])
def test_corrupt_or_foreign_state_is_refused_naming_the_field(edit, needle: str) -> None:
    stats = [WarmupStats.from_features(features(r, EST)) for r in life(3, seed=44)]
    doc = json.loads(json.dumps(LearnState(AXES, stats).to_dict()))
    edit(doc)
    with pytest.raises(CalibrationError) as exc:
        LearnState.from_dict(doc, source="learn.json")
    assert str(exc.value).startswith("learn.json: field ") and needle in str(exc.value)
