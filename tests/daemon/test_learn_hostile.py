"""The [learn] mode's hostile cases (issue 21 item 4): a learning daemon killed mid-write,
a corrupt or foreign file in the state directory, a clock jump during a warm-up, an IMU
that moves at every power-on, two IMUs of which one is broken. Nothing learnt from bad
data is adopted, and nothing already adopted is lost."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.compensation import Calibration, ZeroConfig, read_calibration
from gyrotherm.daemon import _learn_store as store
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.sim._life import power_on
from learnkit import WALL0, boot, frames, life_of

FIVE = LearnConfig(min_warmups=5)
ZERO = ZeroConfig(window_s=30.0, settle_s=30.0)
AMBIENTS_C = (-8.0, 3.0, 14.0, 27.0, 38.0)
LEARNT = "car.imu0.learnt-calibration.json"
STATE = "car.imu0.learn-state.json"


def _good_runs(seed0: int = 500) -> list:
    return [power_on(a, warmup_s=600.0, motion_s=60.0, seed=seed0 + k, name=f"p{k}")
            for k, a in enumerate(AMBIENTS_C)]


@pytest.fixture(scope="module")
def adopted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A state directory after five good power-ons: a learnt calibration adopted."""
    d = tmp_path_factory.mktemp("adopted")
    life_of(d, _good_runs(), config=FIVE, zero=ZERO)
    assert (d / LEARNT).is_file()
    return d


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _bad_learnt(cal: Calibration, **provenance: object) -> Calibration:
    """A learnt calibration for this IMU that removes a constant and no thermal shape."""
    coefficients = {a: (0.0, 0.0, 0.0, 0.0, 0.5) for a in cal.axes}
    return replace(cal, coefficients=coefficients,
                   provenance={**cal.provenance, **provenance})


# --- killed mid-write -------------------------------------------------------------------


def test_a_failed_rename_keeps_the_adopted_file_whole_and_in_use(
        adopted: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    d = _copy(adopted, tmp_path / "s")
    good, _ = read_calibration(d / LEARNT)
    # the previously adopted one, A, learnt from earlier power-ons (a learnt calibration
    # is judged only on warm-ups it was not learnt from)
    text_a, id_a = store.calibration_text(_bad_learnt(good, power_ons=[{"name": "earlier"}]))
    store.write_atomic(d / LEARNT, text_a)
    before = (d / LEARNT).read_bytes()
    real_replace = os.replace

    def dies_at_rename(src: object, dst: object) -> None:
        if str(dst).endswith(LEARNT):
            raise OSError(28, "No space left on device")
        real_replace(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "replace", dies_at_rename)
    b = boot(d, config=FIVE, zero=ZERO)  # the start decides: the learnt model beats A …
    assert b.calibration_id == id_a  # … but the new file was not written: A stays
    assert (d / LEARNT).read_bytes() == before
    assert not (d / f".{LEARNT}.tmp").exists()
    decision = b.learner.record.decision
    assert decision is not None and decision["adopt"] is False
    assert "nothing adopted, the previous file is kept" in decision["reasons"][0]
    assert b.learner.progress.status.startswith("adopted at ")
    assert f"({id_a})" in b.learner.progress.status
    b.feed(frames(power_on(20.0, warmup_s=120.0, seed=3, name="x")))
    b.stop()
    assert b.pipeline.counters().drops == {}
    assert (d / LEARNT).read_bytes() == before
    assert len(b.learner.record.learn.warmups) == 6  # nothing learnt was lost either
    monkeypatch.setattr(os, "replace", real_replace)

    again = boot(d, config=FIVE, zero=ZERO)  # the disk has room again: adopted now
    assert again.calibration_id != id_a, again.learner.record.decision
    cal, cid = read_calibration(d / LEARNT)
    assert cid == again.calibration_id and again.pipeline.calibration == cal
    assert cal.provenance["replaces"] == id_a
    again.stop()


@pytest.mark.parametrize("cut", [0, 100, 2000])
def test_a_daemon_killed_during_the_write_leaves_the_previous_file_loaded(
        adopted: Path, tmp_path: Path, cut: int) -> None:
    """Killed after writing ``cut`` bytes of the temporary file (never renamed)."""
    d = _copy(adopted, tmp_path / "s")
    _, id_before = read_calibration(d / LEARNT)
    good, _ = read_calibration(d / LEARNT)
    text, _ = store.calibration_text(_bad_learnt(good))
    (d / f".{LEARNT}.tmp").write_bytes(text.encode()[:cut])
    b = boot(d, config=FIVE, zero=ZERO)
    assert b.calibration_id == id_before and b.learner.refused == []
    b.stop()


# --- corrupt and foreign files ------------------------------------------------------------


def _configured(adopted: Path) -> tuple[Calibration, str]:
    cal, _ = read_calibration(adopted / LEARNT)
    chamber = replace(cal, provenance={"method": "chamber, by hand"})
    return chamber, store.calibration_text(chamber)[1]


def _learnt_for(adopted: Path, sensor: str) -> bytes:
    cal, _ = read_calibration(adopted / LEARNT)
    other = replace(cal, provenance={**cal.provenance,
                                     "learnt_for": {"vehicle": "car", "sensor": sensor}})
    return store.calibration_text(other)[0].encode()


@pytest.mark.parametrize(("content", "why"), [
    (b"\xff{garbage", "not UTF-8 text"),
    (b"\x00{garbage", "not valid JSON"),
    (b'{"schema": "gyrotherm.calibration", "version": 1', "not valid JSON"),
    (json.dumps({"schema": "gyrotherm.effects-state", "version": 1}).encode(), "field"),
    ("imu1", "not a calibration learnt for 'car'/'imu0'"),
    ("chamber", "not a calibration learnt for 'car'/'imu0'"),
])
def test_a_corrupt_or_foreign_learnt_file_is_refused_and_the_configured_one_used(
        adopted: Path, tmp_path: Path, content: bytes | str, why: str) -> None:
    d = _copy(adopted, tmp_path / "s")
    configured, cid = _configured(adopted)
    if content == "imu1":
        content = _learnt_for(adopted, "imu1")
    elif content == "chamber":
        content = store.calibration_text(configured)[0].encode()
    assert isinstance(content, bytes)
    (d / LEARNT).write_bytes(content)
    b = boot(d, config=FIVE, zero=ZERO, configured=configured, configured_id=cid)
    assert b.calibration_id == cid and b.pipeline.calibration == configured
    assert len(b.learner.refused) == 1
    assert str(d / LEARNT) in b.learner.refused[0] and why in b.learner.refused[0]
    assert not (d / LEARNT).exists() and (d / f"{LEARNT}.refused").read_bytes() == content
    assert len(b.learner.record.learn.warmups) == 5  # the learning state is untouched
    b.feed(frames(power_on(20.0, warmup_s=120.0, seed=3, name="x")))
    b.stop()
    assert b.pipeline.counters().drops == {}
    assert not b.learner.progress.status.startswith("adopted")


def _state_doc(adopted: Path) -> dict:
    return json.loads((adopted / STATE).read_text())


@pytest.mark.parametrize(("make", "why"), [
    (lambda doc: b"[[[[", "not valid JSON"),
    (lambda doc: json.dumps({**doc, "schema": "gyrotherm.fleet"}).encode(), "'schema'"),
    (lambda doc: json.dumps({**doc, "sensor": "imu1"}).encode(), "not of this IMU"),
    (lambda doc: json.dumps(doc).replace('"n": ', '"n": -', 1).encode(), "warmups[0].n"),
    (lambda doc: json.dumps(doc).replace('"sz": [', '"sz": [NaN, ', 1).encode(),
     "NaN is not a finite number"),
])
def test_a_corrupt_or_foreign_learning_state_starts_afresh_and_keeps_the_adoption(
        adopted: Path, tmp_path: Path, make: object, why: str) -> None:
    d = _copy(adopted, tmp_path / "s")
    _, id_adopted = read_calibration(d / LEARNT)
    (d / STATE).write_bytes(make(_state_doc(adopted)))  # type: ignore[operator]
    b = boot(d, config=FIVE, zero=ZERO)
    assert b.calibration_id == id_adopted  # nothing adopted is lost
    assert len(b.learner.refused) == 1 and why in b.learner.refused[0]
    assert (d / f"{STATE}.refused").exists()
    assert b.learner.record.learn.warmups == [] and b.learner.record.rejected == {}
    b.feed(frames(power_on(20.0, warmup_s=120.0, seed=3, name="x")))
    b.stop()
    saved = json.loads((d / STATE).read_text())  # a fresh, valid state of this IMU
    assert saved["sensor"] == "imu0" and len(saved["learn"]["warmups"]) == 1


# --- a clock jump during a warm-up ------------------------------------------------------


@pytest.mark.parametrize("jump_s", [3 * 3600.0, -3 * 3600.0])
def test_a_clock_jump_during_a_warm_up_rejects_it(tmp_path: Path, jump_s: float) -> None:
    """At 200 s the sensor's stamps jump by hours while frames keep coming (the wall clock
    runs on): the warm-up is left out as ``clock_jump`` and nothing after the jump, whose
    t_on would be wrong, is collected."""
    run = power_on(10.0, warmup_s=600.0, seed=11, name="jump")
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    for msg in frames(run):
        wall = WALL0 + msg.timestamp
        if msg.timestamp >= 200.0:
            msg.timestamp += jump_s
        b.pipeline.process(msg, wall)
    assert b.learner.progress.collecting is False  # nothing collected after the jump
    b.stop()
    assert b.learner.record.rejected == {"clock_jump": 1}
    assert b.learner.record.learn.warmups == []
    assert "clock_jump" in b.learner.progress.status
    assert b.pipeline.time_base_changes["temperature"] == 1


def test_a_clock_jump_then_a_real_power_on_learns_again(tmp_path: Path) -> None:
    run = power_on(10.0, warmup_s=300.0, seed=11, name="jump")
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    for msg in frames(run):
        wall = WALL0 + msg.timestamp
        if msg.timestamp >= 200.0:
            msg.timestamp += 3 * 3600.0
        b.pipeline.process(msg, wall)
    b.stop()
    life_of(tmp_path, [power_on(20.0, warmup_s=300.0, seed=12, name="next")], config=FIVE,
            zero=ZERO)
    rec = store.load_record(tmp_path / STATE, vehicle="car", sensor="imu0",
                            axes=("x", "y", "z"))
    assert rec is not None and rec.rejected == {"clock_jump": 1}
    assert len(rec.learn.warmups) == 1


# --- an IMU that moves at every power-on --------------------------------------------------


def test_an_imu_moving_at_every_power_on_never_adopts_and_says_motion(tmp_path: Path) -> None:
    runs = [power_on(a, warmup_s=3.0, motion_s=400.0, seed=40 + k, name=f"m{k}")
            for k, a in enumerate(AMBIENTS_C * 2)]
    boots = life_of(tmp_path, runs, config=LearnConfig(), zero=ZERO)
    last = boots[-1].states()[-1].learn
    assert last is not None and last.warmups_used == 0
    assert last.rejected == {"motion": len(runs)}
    assert "motion" in last.status and last.status.startswith("learning: need 3")
    assert not (tmp_path / LEARNT).exists()
    assert all(b.pipeline.calibration is None for b in boots)


# --- two IMUs, one broken -------------------------------------------------------------------


def test_two_imus_one_broken_the_good_one_learns_alone_as_it_would_alone(
        tmp_path: Path) -> None:
    """imu1 moves at every power-on, and its state directory files are garbage; imu0
    shares the directory (and the power cycles) and adopts exactly what it adopts alone."""
    shared, alone = tmp_path / "shared", tmp_path / "alone"
    shared.mkdir()
    alone.mkdir()
    (shared / "car.imu1.learnt-calibration.json").write_bytes(b"\xff\xfe")
    (shared / "car.imu1.learn-state.json").write_text('{"schema": "gyrotherm.learn-state"}')
    good = _good_runs()
    broken = [power_on(a, warmup_s=2.0, motion_s=700.0, seed=70 + k, name=f"b{k}")
              for k, a in enumerate(AMBIENTS_C)]
    for run0, run1 in zip(good, broken, strict=True):  # one power cycle: both restart
        b0 = boot(shared, sensor="imu0", config=FIVE, zero=ZERO)
        b1 = boot(shared, sensor="imu1", config=FIVE, zero=ZERO)
        f0, f1 = frames(run0), frames(run1)
        for i in range(max(len(f0), len(f1))):  # interleaved, as on one bus
            for b, f in ((b0, f0), (b1, f1)):
                if i < len(f):
                    b.pipeline.process(f[i], WALL0 + f[i].timestamp)
        b0.stop()
        b1.stop()
    assert b1.pipeline.calibration is None
    assert b1.learner.record.rejected == {"motion": 5}
    assert not (shared / "car.imu1.learnt-calibration.json").exists()
    assert b0.pipeline.calibration is not None
    life_of(alone, good, config=FIVE, zero=ZERO)
    cal_shared, _ = read_calibration(shared / LEARNT)
    cal_alone, _ = read_calibration(alone / LEARNT)
    for a in "xyz":
        np.testing.assert_array_equal(cal_shared.coefficients[a], cal_alone.coefficients[a])
    assert len(cal_shared.provenance["power_ons"]) == 5
    assert b0.learner.record.rejected == {}


# --- the status command on a hostile directory --------------------------------------------


def test_learn_status_reports_a_state_dir_with_a_refused_file(
        adopted: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from gyrotherm.cli import main

    d = _copy(adopted, tmp_path / "s")
    assert main(["learn", "status", "--state-dir", str(d)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("car/imu0: adopted at ") and "warm-ups used 5" in out
    (d / LEARNT).write_text(_learnt_for(adopted, "imu1").decode())
    assert main(["learn", "status", "--state-dir", str(d), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (imu,) = doc["imus"]
    assert imu["learnt_calibration"] is None and "learnt_for" in imu["learnt_refused"]
    assert imu["warmups_used"] == 5 and not imu["status"].startswith("adopted")
    (d / STATE).write_text("{}")
    assert main(["learn", "status", "--state-dir", str(d)]) == 2
    assert "cannot be read" in capsys.readouterr().out
    assert main(["learn", "status", "--state-dir", str(tmp_path / "s" / "..")]) == 1


@pytest.mark.parametrize(("decision", "field"), [
    ({"reasons": 5, "warmups": 0}, "decision.reasons"),
    ({"reasons": {"a": 1}, "warmups": 0}, "decision.reasons"),
    ({"reasons": ["x"], "warmups": 0, "candidate_heldout_rms_dps": {"x": "0.1"},
      "current_heldout_rms_dps": {"x": 0.2}}, "decision.candidate_heldout_rms_dps"),
])
def test_a_learning_state_with_a_malformed_decision_is_refused_not_fatal(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], decision: dict,
        field: str) -> None:
    """The status reads the saved decision's reasons and figures: a state whose decision
    is valid JSON of another shape is refused naming the field (learn status: exit 2; the
    daemon: quarantined, learning afresh), not a crash of the daemon's start."""
    from gyrotherm.cli import main
    from gyrotherm.compensation._learnstate import LearnState

    store.save_record(tmp_path / STATE, store.LearnRecord(
        "car", "imu0", LearnState(("x", "y", "z")), decision=decision))
    assert main(["learn", "status", "--state-dir", str(tmp_path)]) == 2
    assert f"field {field!r}" in capsys.readouterr().out
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    assert len(b.learner.refused) == 1 and field in b.learner.refused[0]
    assert (tmp_path / f"{STATE}.refused").exists()


def test_learn_status_on_a_state_whose_axes_are_not_a_list_names_the_field(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``learn.axes`` of another type is the file's fault (exit 2, the field named), not
    an internal error of the command; a held-out figure written as null (not finite) is
    left out of the text, not a crash."""
    from gyrotherm.cli import main
    from gyrotherm.compensation._learnstate import LearnState

    rec = store.LearnRecord("car", "imu0", LearnState(("x", "y", "z")), decision={
        "reasons": ["r"], "warmups": 0, "candidate_heldout_rms_dps": {"x": None, "y": 0.1},
        "current_heldout_rms_dps": {"x": 0.2, "y": 0.3}})
    store.save_record(tmp_path / STATE, rec)
    assert main(["learn", "status", "--state-dir", str(tmp_path)]) == 0
    assert "learnt vs in use: y 0.1000 vs 0.3000 °/s" in capsys.readouterr().out
    doc = _state_doc(tmp_path)
    for axes in (5, "xyz", [["x"]]):
        doc["learn"]["axes"] = axes
        (tmp_path / STATE).write_text(json.dumps(doc))
        assert main(["learn", "status", "--state-dir", str(tmp_path)]) == 2
        assert "field 'axes'" in capsys.readouterr().out


def test_a_learnt_calibration_its_own_loader_would_refuse_is_not_adopted(
        tmp_path: Path) -> None:
    """A learning state whose numbers are finite but not physical (one warm-up's T range
    −1000…1000 °C: the validated extrapolation widens the learnt range past the
    calibration loader's −100…200 °C) is not adopted: the running daemon would swap it in
    and refuse it at its next start. The decision says why; nothing is written."""
    from gyrotherm.compensation import features
    from gyrotherm.compensation._learn import WarmupStats
    from gyrotherm.compensation._learnstate import LearnState
    from learnkit import EST

    stats = [WarmupStats.from_features(features(power_on(a, seed=700 + k, name=f"w{k}"), EST))
             for k, a in enumerate(AMBIENTS_C)]
    good = LearnState(("x", "y", "z"), list(stats))
    (tmp_path / "good").mkdir()
    store.save_record(tmp_path / "good" / STATE, store.LearnRecord("car", "imu0", good))
    assert boot(tmp_path / "good", config=FIVE).learner.adopted  # these warm-ups adopt
    stats[0] = replace(stats[0], t_range_c=(-1000.0, 1000.0))
    store.save_record(tmp_path / STATE, store.LearnRecord(
        "car", "imu0", LearnState(("x", "y", "z"), stats)))
    b = boot(tmp_path, config=FIVE)
    assert not b.learner.adopted and not (tmp_path / LEARNT).exists()
    (why,) = b.learner.record.decision["reasons"]
    assert "would be refused" in why and "outside [-100, 200]" in why
