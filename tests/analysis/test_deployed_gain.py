"""Deployed gain (scripts/deployed_gain.py): an extended calibration from
``diagnose --calibration`` semantics, applied to a held-out run of the independent
generator offline (``removed_bias`` on the offline features) and streamed through the
daemon's real Pipeline, scored the same way (bias error against the generator's truth on
the same rows). With a stateful effect (hysteresis) it removes the true bias better than
the paper calibration, the two sources agree, and the criterion (deployed ≥ 80 % of
offline, offset removed) is met; with nothing injected it is no worse than paper by more
than 3 %. The script's default settings and first seed of record, one zero window (300 s)
and no PX4 row to keep the test at ≈ 25 s; the tables, their medians and counts on
hand-made rows."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import pytest

WINDOW = 300.0


@pytest.fixture(scope="module")
def script(deployed_gain: ModuleType) -> ModuleType:
    return deployed_gain


def _row(script: ModuleType, effect: str) -> dict[str, Any]:
    assert WINDOW in script.ZERO_WINDOWS_S
    row: dict[str, Any] = script.one_effect(effect, script.FULL, script.SEED,
                                            windows=(WINDOW,), px4=False)
    return row


def _same_quantity(script: ModuleType, cell: dict[str, Any]) -> None:
    """Offline and deployed: the same calibrations scored on the same rows agree (the
    vehicle's estimator and the offline features, the wire's quantisation apart)."""
    for c in script.CALIBRATIONS:
        off, dep = cell["offline"][c], cell["deployed"][c]
        assert dep["rms"] == pytest.approx(off["rms"], rel=0.05), (c, off, dep)


def test_hysteresis_extended_beats_paper_offline_and_deployed(script: ModuleType) -> None:
    row = _row(script, "hysteresis")
    assert row["seed"] == 101 and row["extended_effects"] == ["hysteresis"]
    nz = row["no_zero"]
    assert nz["rows"] > 0.99 * script.FULL.duration_s * script.FULL.rate_hz
    _same_quantity(script, nz)
    for source in ("offline", "deployed"):
        assert script.gain(nz[source]) > 1.5
        assert script.gain(nz[source], "rms_offset_removed") > 3.0
    assert script.met(row, None)
    z = row["zero"][str(WINDOW)]
    _same_quantity(script, z)
    assert all(s == "done at 330 s" for src in z["status"].values() for s in src.values())
    assert z["deployed"]["extended"]["rms"] < nz["deployed"]["extended"]["rms"]  # floor gone
    assert script.met(row, str(WINDOW))
    assert script.ratio(row, str(WINDOW)) == pytest.approx(
        script.gain(z["deployed"]) / script.gain(z["offline"]))


def test_nothing_injected_extended_no_worse_than_paper(script: ModuleType) -> None:
    row = _row(script, "none")
    assert row["found"] == [] and row["extended_effects"] == []
    for cell in (row["no_zero"], row["zero"][str(WINDOW)]):
        _same_quantity(script, cell)
        for key in ("rms", "rms_offset_removed"):
            r = cell["deployed"]
            assert r["extended"][key] <= script.NONE_TOLERANCE * r["paper"][key], (key, r)
    assert script.met(row, None) and script.met(row, str(WINDOW))


def test_zeroed_error_hand_computed(script: ModuleType) -> None:
    """``zeroed_error`` on a hand-made run: 10 Hz, a true bias of 0.1 °/s + 0.001 °/s
    per s, switch-on offset 0.03 °/s. A daemon whose zero caught the offset exactly
    removes truth + 0.03 from 40 s on (before: truth + 0.02, a calibration whose
    intercept is off): scored from 40 s the error is 0; from 30 s, 100 of the 300 rows
    are off by −0.01 °/s: RMS = 0.01·√(1/3)."""
    import numpy as np

    from gyrotherm.codecs import Run

    t = np.arange(0.0, 60.0, 0.1)
    truth = 0.1 + 0.001 * t
    run = Run(name="hand", time_s=t + 1000.0, temperature_c=np.full(len(t), 20.0),
              rates_dps={"x": truth + 0.03}, true_bias_dps={"x": truth},
              metadata={"switch_on_offset_dps": "0.03"})
    removed = truth + np.where(t >= 40.0 - 1e-9, 0.03, 0.02)
    assert script.zeroed_error(run, removed, 40.0) == pytest.approx(0.0, abs=1e-12)
    assert script.zeroed_error(run, removed, 30.0) == pytest.approx(0.01 / np.sqrt(3),
                                                                    rel=1e-6)


def _fake(effect: str, seed: int, paper_off: float, ext_off: float, paper_dep: float,
          ext_dep: float) -> dict[str, Any]:
    """A row with RMS values only (offset removed = as is), diagnosis' gain 2."""
    def s(paper: float, ext: float) -> dict[str, dict[str, float]]:
        return {"paper": {"rms": paper, "rms_offset_removed": paper, "mean": 0.0},
                "extended": {"rms": ext, "rms_offset_removed": ext, "mean": 0.0}}

    scores = {"rows": 10, "offline": s(paper_off, ext_off), "deployed": s(paper_dep, ext_dep)}
    return {"effect": effect, "seed": seed, "found": [effect], "diagnosis_gain": 2.0,
            "no_zero": scores,
            "zero": {"10.0": {**scores, "no_zero_same_rows": s(paper_dep, ext_dep),
                              "status": {"deployed": {"paper": "done at 40 s"},
                                         "offline": {"paper": "pending"}}}}}


def test_tables_median_range_and_criterion_counted(script: ModuleType) -> None:
    """Three seeds of one effect, offline gain 4 each; deployed gains 4, 3 and 2
    (ratios 100, 75, 50 %): median 3 [2–4], 75 % [50–100], criterion met on 1 of 3;
    deployed / diagnosis' gain (2) 150 % [100–200], all three ≥ 80 %."""
    rows = [_fake("cubic", 103, 0.04, 0.01, 0.04, 0.01),
            _fake("cubic", 101, 0.04, 0.01, 0.03, 0.01),
            _fake("cubic", 102, 0.04, 0.01, 0.02, 0.01)]
    assert [r["seed"] for r in script.by_effect(rows)["cubic"]] == [101, 102, 103]
    assert script.Spread.of([3.0, 1.0, 2.0, 5.0, 4.0]) == script.Spread(3.0, 1.0, 5.0)
    assert [script.met(r, None) for r in rows] == [True, False, False]
    line = script.no_zero_table(rows)[2].split(" | ")
    assert line[0] == "| cubic" and line[1] == "3/3"
    assert line[3] == "4.00 [4.00–4.00]" and line[4] == "3.00 [2.00–4.00]"
    assert line[7] == "75 % [50–100]" and line[8] == "1/3"
    assert line[9] == "150 % [100–200]" and line[10] == "3/3"
    zero = script.zero_table(rows)[2].split(" | ")
    assert zero[1] == "10 s" and zero[4] == "75 % [50–100]" and zero[5] == "1/3"
    assert zero[6] == "0.0300 / 0.0300 → 0.0300 (×1.00 [1.00–1.00])"
    assert zero[8] == "3/6 |"
    assert script.criterion_table(rows)[2] == "| cubic | 1/3 | 1/3 | 3/3 | 3/3 |"
