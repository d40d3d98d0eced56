"""[learn] across daemon restarts (issue 21 item 4): a daemon killed in the middle of a
warm-up (no shutdown save) and restarted while the gyro keeps running, and a gyro that
power-cycled while the daemon was down, are not learnt, each counted by its reason
(``restart``, ``missed_start``); a clean power-on after them is. The truth is the
simulator's: each run's power-on is its stamp 0 (on the gyro's own clock) and the tests
choose where the daemon comes back in it.

One daemon start per ``boot`` (tests/learnkit.py), fed with a simulated wall clock that
runs with the gyro's (``wall_offset_s``: where the gyro's power-on is on the wall clock);
a "kill" is a boot that is never stopped (the state dir holds what it saved, as after
``kill -9``). The real-process case is ``test_learn_restart_process.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrotherm.codecs._candump_run import POWER_ON_LIMIT_S
from gyrotherm.compensation import ZeroConfig
from gyrotherm.daemon import _learn_store as store
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.daemon._learner import DEVICE_CLOCK_LIMIT_S, FIRST_FRAME_MAX_S
from gyrotherm.sim._life import power_on
from learnkit import WALL0, Boot, boot, frames

FIVE = LearnConfig(min_warmups=5, min_rest_s=60.0, warmup_window_s=900.0)
ZERO = ZeroConfig(window_s=30.0, settle_s=30.0)
STATE = "car.imu0.learn-state.json"
KILL_S = 300.0  # the first daemon dies this long after the power-on (sensor time)


def _record(d: Path) -> store.LearnRecord:
    rec = store.load_record(d / STATE, vehicle="car", sensor="imu0", axes=("x", "y", "z"))
    assert rec is not None
    return rec


def _feed(b: Boot, msgs: list, *, start_s: float = -1.0, stop_s: float = 1e18,
          wall_offset_s: float = 0.0) -> None:
    b.feed([m for m in msgs if start_s <= m.timestamp < stop_s], wall_offset_s=wall_offset_s)


def _killed_mid_warm_up(d: Path, *, shift_s: float = 0.0, wall_offset_s: float = 0.0
                        ) -> tuple[list, bytes]:
    """A daemon that learnt nothing yet takes a power-on and is killed KILL_S into its
    warm-up; the run's frames and the state file as the kill left it."""
    run = power_on(12.0, warmup_s=600.0, seed=31, name="a")
    msgs = frames(run, shift_s=shift_s)
    first = boot(d, config=FIVE, zero=ZERO)
    _feed(first, msgs, stop_s=shift_s + KILL_S, wall_offset_s=wall_offset_s)
    assert first.learner.progress.collecting  # killed while collecting: no save since
    saved = (d / STATE).read_bytes()
    rec = _record(d)
    assert rec.power_ons == 1 and rec.learn.warmups == [] and rec.rejected == {}
    assert rec.power_on_time_s == msgs[0].timestamp  # saved at the power-on itself
    assert rec.last_time_s < shift_s + KILL_S - 60.0  # more than 60 s stale
    return msgs, saved


def test_the_device_clock_limit_is_the_codecs_convention() -> None:
    assert DEVICE_CLOCK_LIMIT_S == POWER_ON_LIMIT_S


def test_a_daemon_killed_mid_warm_up_and_restarted_while_the_gyro_runs_is_a_restart(
        tmp_path: Path) -> None:
    msgs, saved = _killed_mid_warm_up(tmp_path)
    back_s = KILL_S + 60.0  # down for a minute, the gyro running on
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    _feed(b, msgs, start_s=back_s)
    assert not b.learner.progress.collecting
    assert b.learner.progress.rejected == {"restart": 1}
    assert b.learner.progress.status.endswith("last power-on left out: restart (1 so far)")
    b.stop()
    rec = _record(tmp_path)
    before = json.loads(saved)
    assert rec.power_ons == before["power_ons"] == 1  # not counted again
    assert rec.learn.to_dict() == before["learn"] and rec.learn.warmups == []
    assert rec.rejected == {"restart": 1}
    assert not (tmp_path / "car.imu0.learnt-calibration.json").exists()


@pytest.mark.parametrize("back_s", [200.0, 400.0])
def test_a_gyro_power_cycled_while_the_daemon_was_down_is_a_missed_start(
        tmp_path: Path, back_s: float) -> None:
    """Killed KILL_S into power-on A; the gyro is off 20 s and powers on again (B, its
    stamps from 0); the daemon comes back ``back_s`` into B (before and after A's kill
    on the gyro's clock)."""
    _killed_mid_warm_up(tmp_path)
    b_run = power_on(25.0, warmup_s=600.0, seed=32, name="b")
    b_on_wall_s = KILL_S + 20.0  # B's power-on on the wall clock (A's at 0)
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    msgs = frames(b_run)
    _feed(b, msgs, start_s=back_s, wall_offset_s=b_on_wall_s)
    first = next(m.timestamp for m in msgs if m.timestamp >= back_s)
    assert first - b_run.time_s[0] > FIRST_FRAME_MAX_S  # the truth: B began unseen
    assert not b.learner.progress.collecting
    assert b.learner.progress.rejected == {"missed_start": 1}
    assert "last power-on left out: missed_start (1 so far)" in b.learner.progress.status
    b.stop()
    rec = _record(tmp_path)
    assert rec.power_ons == 1 and rec.learn.warmups == [] and rec.rejected == {
        "missed_start": 1}


def test_a_first_start_late_in_a_power_on_is_a_missed_start(tmp_path: Path) -> None:
    """No learning state yet, the daemon starts 100 s after the gyro's power-on."""
    run = power_on(12.0, warmup_s=400.0, seed=33, name="late")
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    _feed(b, frames(run), start_s=100.0)
    b.stop()
    rec = _record(tmp_path)
    assert rec.power_ons == 0 and rec.learn.warmups == [] and rec.rejected == {
        "missed_start": 1}


def test_host_clock_stamps_a_kill_mid_warm_up_is_a_restart(tmp_path: Path) -> None:
    """Stamps of a host's clock (beyond 10⁶ s, SocketCAN's receive times: the wall clock
    itself) say nothing about the gyro's power-on: the kill left the power-on's stamp in
    the state, and a first frame inside its window is a restart."""
    host0 = 1.7e9
    msgs, _ = _killed_mid_warm_up(tmp_path, shift_s=host0, wall_offset_s=-WALL0)
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    _feed(b, msgs, start_s=host0 + KILL_S + 60.0, wall_offset_s=-WALL0)
    b.stop()
    rec = _record(tmp_path)
    assert rec.power_ons == 1 and rec.learn.warmups == [] and rec.rejected == {"restart": 1}
    assert rec.power_on_time_s != rec.power_on_time_s  # a clean stop clears it (NaN)


@pytest.mark.parametrize("how", ["restart", "missed_start"])
def test_a_clean_power_on_after_a_left_out_restart_is_learnt(tmp_path: Path,
                                                             how: str) -> None:
    msgs, _ = _killed_mid_warm_up(tmp_path)
    b = boot(tmp_path, config=FIVE, zero=ZERO)
    if how == "restart":
        _feed(b, msgs, start_s=KILL_S + 60.0)
    else:
        _feed(b, frames(power_on(25.0, warmup_s=600.0, seed=32, name="b")), start_s=200.0,
              wall_offset_s=KILL_S + 20.0)
    b.stop()
    # the gyro powers off, and on with the daemon (its stamps from 0 again)
    c_run = power_on(3.0, warmup_s=300.0, seed=34, name="c")
    c = boot(tmp_path, config=FIVE, zero=ZERO)
    _feed(c, frames(c_run), wall_offset_s=5000.0)
    assert c.learner.progress.collecting
    c.stop()
    rec = _record(tmp_path)
    assert rec.power_ons == 2 and len(rec.learn.warmups) == 1 and rec.rejected == {how: 1}
    assert rec.learn.warmups[0].start_c == pytest.approx(3.0, abs=1.0)
