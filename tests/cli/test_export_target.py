"""``export --cubic-target``: the cubic in T fitted to the rows at rest, or to the
calibration's steady state (its bias at ΔT = 0), or chosen by the lower held-out error.

Independent truth: the paper model at ΔT = 0 is a quadratic in T (a1·T² + a2·T + a5), so
the ``model`` cubic must reproduce ``Calibration.bias_at(T, 0)`` to rounding over the
calibration's valid range; ``auto`` must pick the target whose held-out error is lower,
and write exactly the parameters that target writes when asked for by name."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.compensation import load_calibration


@pytest.fixture(scope="module")
def fitted(chamber_fit: tuple[Path, list[Path], Path, Path]) -> tuple[Path, Path]:
    _, _, valid, cal = chamber_fit
    return cal, valid


def _export(cal: Path, valid: Path, target: str, out: Path) -> dict:  # type: ignore[type-arg]
    js = out.with_suffix(".json")
    assert main(["-q", "export", str(cal), "--ardupilot", str(out), "--validate", str(valid),
                 "--cubic-target", target, "--json", str(js)]) == 0
    return json.loads(js.read_text())  # type: ignore[no-any-return]


def test_the_model_cubic_is_the_calibrations_steady_state(fitted: tuple[Path, Path],
                                                          tmp_path: Path) -> None:
    cal, valid = fitted
    doc = _export(cal, valid, "model", tmp_path / "m.param")
    c = doc["cubic"]
    calibration = load_calibration(cal)
    r = calibration.valid_range  # the model is clamped outside it, the cubic is not
    t = np.linspace(max(c["t_min_c"], r.t_min_c), min(c["t_max_c"], r.t_max_c), 50)
    for axis, coef in c["coefficients_rad_s"].items():
        u = t - c["t_ref_c"]
        cubic = sum(k * u**i for i, k in enumerate(coef))
        want = np.radians([calibration.bias_at(float(x), 0.0).bias_dps[axis] for x in t])
        np.testing.assert_allclose(cubic, want, atol=1e-12)


def test_auto_picks_the_lower_held_out_error(fitted: tuple[Path, Path],
                                            tmp_path: Path) -> None:
    cal, valid = fitted
    auto = _export(cal, valid, "auto", tmp_path / "a.param")
    scores = auto["cubic_target"]["heldout_cubic_rms_dps"]
    assert set(scores) == {"rows", "model"}
    chosen = auto["cubic_target"]["chosen"]
    assert chosen == min(scores, key=scores.get)
    named = {k: _export(cal, valid, k, tmp_path / f"{k}.param") for k in ("rows", "model")}
    for k, doc in named.items():  # each target's own held-out error, recomputed
        rms = np.mean([e["cubic_rms_dps"] for e in doc["validation"]["axes"].values()])
        assert rms == pytest.approx(scores[k], rel=1e-12)
    assert (tmp_path / "a.param").read_text() == (tmp_path / f"{chosen}.param").read_text()
