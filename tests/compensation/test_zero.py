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
    bz = BootZero(CFG)
    assert bz.status == ZeroStatus.OFF and not bz.push(0.0, 0.0, 0.0, 0.0)
    saved = {"status": "done", "offset_dps": [0.1, 0.2, 0.3], "done_s": 5.0}
    assert bz.restore(check_saved(saved, "state.json"), 8.0)
    assert bz.status == ZeroStatus.DONE and bz.offset_dps == (0.1, 0.2, 0.3)
    assert bz.to_dict() == saved
    assert not bz.restore({**saved, "status": "failed"}, 9.0)  # measured again from 9 s
    assert bz.status == ZeroStatus.PENDING and bz.start_s == 9.0
    assert not bz.restore(None, 9.5) and bz.start_s == 9.5
    with pytest.raises(CalibrationError, match=r"state.json: field 'zero.offset_dps'"):
        check_saved({**saved, "offset_dps": [0.1, "x", 0.3]}, "state.json")
    bz.start(10.0)
    assert bz.status == ZeroStatus.PENDING and bz.offset_dps == (0.0, 0.0, 0.0)
    bz.stop()
    assert bz.status == ZeroStatus.OFF


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
