"""The boot-time zero (gyrotherm.compensation._zero) against hand-computed windows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrotherm import CalibrationError, ConfigError
from gyrotherm.compensation._zero import (
    BootZero,
    ZeroConfig,
    ZeroStatus,
    check_saved,
    zero_series,
)

CFG = ZeroConfig(window_s=4.0, settle_s=2.0, max_std_dps=0.1, max_step_dps=0.02,
                 max_offset_dps=0.5, deadline_s=30.0)


def _series(residual_x: np.ndarray, rate_hz: float = 10.0) -> np.ndarray:
    return np.arange(len(residual_x)) / rate_hz


def test_accepted_window_is_the_hand_computed_mean() -> None:
    """10 Hz, settle 2 s, window 4 s: the window opens at t = 2.0 (row 20) and is
    closed by the first row at t ≥ 6.0 (row 60); z = mean of rows 20..59 on each axis,
    removed from row 60 on."""
    rng = np.random.default_rng(7)
    n = 200
    x = 0.03 + rng.normal(0.0, 0.01, n)
    y = -0.2 + rng.normal(0.0, 0.01, n)
    t = _series(x)
    zs = zero_series(CFG, t, {"x": x, "y": y})
    assert zs.status == ZeroStatus.DONE and zs.windows_rejected == 0
    assert zs.done_s == pytest.approx(6.0)
    want_x, want_y = float(np.mean(x[20:60])), float(np.mean(y[20:60]))
    assert zs.offset_dps["x"][60] == pytest.approx(want_x, abs=1e-15)
    assert zs.offset_dps["y"][60] == pytest.approx(want_y, abs=1e-15)
    assert np.all(zs.offset_dps["x"][:60] == 0.0) and np.all(zs.offset_dps["x"][60:] == want_x)
    assert "z" not in zs.offset_dps  # absent axes are not invented


def test_motion_in_the_first_window_is_refused_and_the_next_one_taken() -> None:
    """A 1 °/s turn in 3.0–3.5 s (inside the first window): std and step fail, a new
    window opens at the closing row 60 (t = 6.0) and closes at row 100."""
    x = np.full(300, 0.04)
    x[30:35] += 1.0
    t = _series(x)
    zs = zero_series(CFG, t, {"x": x})
    assert zs.status == ZeroStatus.DONE and zs.windows_rejected == 1
    assert zs.done_s == pytest.approx(10.0)
    assert zs.offset_dps["x"][100] == pytest.approx(0.04, abs=1e-12)
    assert np.all(zs.offset_dps["x"][:100] == 0.0)


def test_a_slow_drift_fails_the_step_check() -> None:
    """A residual ramping 0.02 °/s per s (std over a 4-s window ≈ 0.023 °/s, within
    max_std): the half-window means differ by 0.04 °/s > max_step 0.02, so every window
    is refused until the deadline: FAILED, nothing removed."""
    t = np.arange(400) / 10.0
    x = 0.02 * t
    zs = zero_series(CFG, t, {"x": x})
    assert zs.status == ZeroStatus.FAILED and zs.windows_rejected >= 6
    assert np.all(zs.offset_dps["x"] == 0.0)


def test_a_steady_turn_beyond_max_offset_is_not_an_offset() -> None:
    t = np.arange(400) / 10.0
    zs = zero_series(CFG, t, {"x": np.full(400, 0.6)})
    assert zs.status == ZeroStatus.FAILED
    below = zero_series(CFG, t, {"x": np.full(400, 0.4)})  # the documented limit
    assert below.status == ZeroStatus.DONE and below.offset_dps["x"][-1] == pytest.approx(0.4)


def test_non_finite_sample_discards_the_open_window() -> None:
    x = np.full(200, 0.01)
    x[45] = math.nan  # inside the first window (rows 20..59)
    t = _series(x)
    zs = zero_series(CFG, t, {"x": x})
    # a new window opens at row 46 (t = 4.6) and closes at row 86 (t = 8.6)
    assert zs.status == ZeroStatus.DONE and zs.done_s == pytest.approx(8.6)
    assert zs.windows_rejected == 0


def test_unusable_samples_do_not_stop_the_deadline() -> None:
    """Every sample unusable (on the vehicle: stale, bias-invalid, sensor fault): the
    window never opens, and the zero fails at the deadline counted from the first one."""
    bz = BootZero(CFG)
    bz.start()  # NaN: the start is the first sample, usable or not
    changed = [bz.interrupt(100.0 + 0.5 * i) for i in range(80)]
    assert bz.start_s == 100.0 and bz.status == ZeroStatus.FAILED
    assert changed.index(True) == 61  # t = 130.5 s: the first beyond 30 s


def test_restart_and_restore() -> None:
    """A restart that continues the gyro's run (power-on at 1 s, latest saved step at
    8 s): done is kept, failed stays failed, pending goes on from its start; no zero
    saved, or one out of bounds, is measured again from now, untrusted."""
    bz = BootZero(CFG)
    assert bz.status == ZeroStatus.OFF and not bz.push(0.0, 0.0, 0.0, 0.0)
    saved = {"status": "done", "offset_dps": [0.1, 0.2, 0.3], "done_s": 5.0,
             "start_s": 1.0, "trusted": True, "unverified": False}
    run = {"power_on_s": 1.0, "saved_time_s": 8.0}
    assert "kept" in bz.restore(check_saved(saved, "state.json"), 8.5, **run)
    assert bz.status == ZeroStatus.DONE and bz.offset_dps == (0.1, 0.2, 0.3)
    assert bz.to_dict() == {**saved, "start_s": None}
    assert "stays failed" in bz.restore({**saved, "status": "failed"}, 9.0, **run)
    assert bz.status == ZeroStatus.FAILED and bz.offset_dps == (0.0, 0.0, 0.0)
    assert not bz.push(200.0, 0.0, 0.0, 0.0) and bz.status == ZeroStatus.FAILED
    assert "goes on" in bz.restore({**saved, "status": "pending", "start_s": 2.0}, 9.0, **run)
    assert bz.status == ZeroStatus.PENDING and bz.start_s == 2.0 and bz.trusted
    assert "measured again" in bz.restore(None, 9.5, **run)
    assert bz.start_s == 9.5 and not bz.trusted
    for bad, why in [({"offset_dps": [0.1, 0.6, 0.3]}, "offset_dps[1] = 0.6 °/s is beyond "
                      "max_offset_dps = 0.5"),
                     ({"done_s": 9.0}, "done_s = 9.0 s is outside the saved run"),
                     ({"start_s": 0.5}, "start_s = 0.5 s is outside")]:
        assert why in bz.restore({**saved, **bad}, 9.5, **run)
        assert bz.status == ZeroStatus.PENDING and not bz.trusted
    with pytest.raises(CalibrationError, match=r"state.json: field 'zero.offset_dps'"):
        check_saved({**saved, "offset_dps": [0.1, "x", 0.3]}, "state.json")
    with pytest.raises(CalibrationError, match=r"state.json: field 'zero.unverified'"):
        check_saved({**saved, "unverified": 1}, "state.json")
    bz.start(10.0)
    assert bz.status == ZeroStatus.PENDING and bz.offset_dps == (0.0, 0.0, 0.0)
    bz.stop()
    assert bz.status == ZeroStatus.OFF


def test_untrusted_zero_is_unverified_unless_it_agrees_with_its_reference() -> None:
    """Residual 0.1 °/s on x from 10 Hz rows: started untrusted with a reference within
    max_step_dps (0.02) the zero is verified; with one 0.05 away, or none, it is not."""
    t = np.arange(100) / 10.0
    for reference, unverified in [((0.11, 0.0, 0.0), False), ((0.05, 0.0, 0.0), True),
                                  (None, True)]:
        bz = BootZero(CFG)
        bz.start(0.0, trusted=False, reference=reference)
        assert any(bz.push(float(ti), 0.1, 0.0, 0.0) for ti in t)
        assert bz.status == ZeroStatus.DONE and bz.offset_dps[0] == pytest.approx(0.1)
        assert bz.unverified is unverified
    bz = BootZero(CFG)
    bz.start(0.0)
    assert any(bz.push(float(ti), 0.1, 0.0, 0.0) for ti in t) and not bz.unverified


def test_a_time_jump_while_pending_is_not_a_failure() -> None:
    """Rows at 10 Hz, then the stream's clock jumps by +1e6 s (or back by 500 s) at 3 s:
    the deadline (30 s) counts elapsed sensor time, so the zero is still pending right
    after the jump and is taken 2 s + 4 s of usable rows later."""
    for jump in (1e6, -500.0):
        bz = BootZero(CFG)
        bz.start(0.0)
        times = [k / 10.0 for k in range(30)] + [3.0 + jump + k / 10.0 for k in range(100)]
        outcome = [bz.push(ti, 0.1, 0.0, 0.0) for ti in times]
        assert bz.status == ZeroStatus.DONE and bz.done_s > 3.0 + jump
        assert outcome.index(True) > 30


@pytest.mark.parametrize(("key", "value", "match"), [
    ("window_s", 0.5, r"zero.window_s = 0.5 is outside \[1, 3600\]"),
    ("max_std_dps", math.inf, r"zero.max_std_dps = inf is outside"),
    ("deadline_s", 5.0, r"deadline_s = 5 s leaves no room for settle_s \+ window_s = 40 s"),
    ("settle_s", "10", r"zero.settle_s: expected a number, got '10'"),
])
def test_config_errors_name_the_key_and_limit(key: str, value: object, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        ZeroConfig.from_dict({key: value}, where="gyrotherm.toml: [zero]")


def test_config_unknown_key_is_named() -> None:
    with pytest.raises(ConfigError, match=r"\[zero\]: unknown key\(s\) \['window'\]"):
        ZeroConfig.from_dict({"window": 5}, where="gyrotherm.toml: [zero]")
