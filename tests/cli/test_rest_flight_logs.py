"""Rest detection in flight, end to end: generated flight logs (tests/flightkit.py) as a
PX4 ULog and an ArduPilot DataFlash log through ``fit``, ``evaluate`` and ``diagnose``.

Independent truth: the raw rates as pyulog and pymavlink decode them (not gyrotherm's
readers), and the generator's schedule (which rows are armed, which still stretches
are long enough). The rows kept are rebuilt from the ``--json`` rest report's excluded
segments on those independently decoded time stamps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import flightkit as fk
from gyrotherm.cli import main

MAX_RATE_DPS = 5.0


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return fk.write(tmp_path_factory.mktemp("flight"), fk.flight(), "flight")


def raw_rows(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(time s, rates °/s (n, 3)) of the IMU rows as pyulog or pymavlink read them."""
    if path.suffix == ".ulg":
        from pyulog import ULog

        (g,) = [d for d in ULog(str(path), ["sensor_gyro"]).data_list]
        t = g.data["timestamp_sample"].astype(np.float64) * 1e-6
        return t, np.degrees(np.column_stack([g.data[a].astype(np.float64) for a in "xyz"]))
    from pymavlink.DFReader import DFReader_binary

    log = DFReader_binary(str(path))
    rows = []
    while (m := log.recv_match(type="IMU")) is not None:
        rows.append((m.TimeUS * 1e-6, m.GyrX, m.GyrY, m.GyrZ))
    log.close()
    a = np.array(rows)
    return a[:, 0], np.degrees(a[:, 1:])


def kept_mask(t: np.ndarray, report: dict[str, object]) -> np.ndarray:
    segments = report["segments"]
    assert isinstance(segments, list)
    kept = np.ones(len(t), dtype=bool)
    for s in segments:
        kept &= ~((t >= s["start_s"]) & (t <= s["end_s"]))
    return kept


def _fit_json(path: Path, tmp: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    out = tmp / f"fit-{path.suffix[1:]}.json"
    # t2: one 600-s flight does not determine the paper model's ΔT terms (its fit reaches
    # the 30 °/s plausibility bound that evaluate enforces); these tests are about rest
    assert main(["-q", "fit", str(path), "--out", str(tmp / f"cal-{path.suffix[1:]}.json"),
                 "--model", "t2", "--force", "--json", str(out)]) == 0, capsys.readouterr().err
    doc: dict[str, object] = json.loads(out.read_text())
    return doc


@pytest.mark.parametrize("kind", ["ulog", "dataflash"])
def test_no_turning_or_armed_row_is_kept_and_still_stretches_are(
    kind: str, logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    path = logs[kind]
    (report,) = _fit_json(path, tmp_path, capsys)["rest"]["runs"]  # type: ignore[index]
    t, rates = raw_rows(path)
    assert report["rows"] == len(t) == len(fk.flight().time_s)
    kept = kept_mask(t, report)
    assert int(np.count_nonzero(~kept)) == report["excluded_rows"]
    turning = np.linalg.norm(rates, axis=1) > MAX_RATE_DPS
    assert turning.sum() > 2000  # the flight and the turns
    assert not np.any(kept & turning)
    # the schedule, on the log's clock (the log starts BOOT_US after boot)
    flight_t = t - fk.BOOT_US * 1e-6
    truth = fk.flight()
    np.testing.assert_allclose(flight_t, truth.time_s, atol=1e-6)
    assert not np.any(kept & truth.armed)
    for a, b in fk.KEEP_S:
        inside = (flight_t >= a + 2.0) & (flight_t < b - 2.0)
        assert kept[inside].all(), (a, b)
    # 20 s still between the landing (armed) and the 35-s gap, 15 s after it: each too
    # short on its own side, although the gap made them look 70 s long
    for a, b in fk.SHORT_BY_GAP_S:
        assert not kept[(flight_t >= a) & (flight_t < b)].any(), (a, b)
    assert report["gaps"] == 1
    reasons = {r for s in report["segments"] for r in s["reasons"]}
    assert {"armed", "logging gap", "rate above 5 °/s"} <= reasons
    assert 0.4 < np.mean(kept) < 0.6


def test_fit_evaluate_and_diagnose_agree_on_what_is_rest(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    path = logs["ulog"]
    fitted = _fit_json(path, tmp_path, capsys)["rest"]
    out = tmp_path / "scores.json"
    assert main(["-q", "evaluate", str(tmp_path / "cal-ulg.json"), str(path),
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["rest"] == fitted
    capsys.readouterr()
    twin = tmp_path / "again.ulg"  # diagnose takes two runs or more
    twin.write_bytes(path.read_bytes())
    assert main(["-q", "diagnose", str(path), str(twin), "--no-simulation"]) == 2
    err = capsys.readouterr().err
    (report,) = fitted["runs"]  # type: ignore[index]
    first = report["segments"][0]
    assert f"{len(report['segments'])} segments not at rest" in err
    assert f"{first['start_s']:.1f}–{first['end_s']:.1f} s: {'/'.join(first['reasons'])}" in err


@pytest.mark.parametrize("kind", ["ulog", "dataflash"])
def test_a_still_log_shorter_than_the_minimum_is_kept_and_the_report_says_why(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """20 s on the ground, still and disarmed: kept whole, not excluded as 'short rest'."""
    path = fk.write(tmp_path, fk.still_flight(20.0), "still")[kind]
    (report,) = _fit_json(path, tmp_path, capsys)["rest"]["runs"]  # type: ignore[index]
    t, _ = raw_rows(path)
    assert report["excluded_rows"] == 0 and kept_mask(t, report).all()
    assert report["min_segment_s"] == pytest.approx(10.0)
    assert report["note"].startswith("minimum rest stretch 10 s, not 30 s: the log covers 20 s")
    twin = tmp_path / f"again{path.suffix}"  # diagnose takes two runs or more
    twin.write_bytes(path.read_bytes())
    capsys.readouterr()
    main(["-q", "diagnose", str(path), str(twin), "--no-simulation"])  # may fail otherwise
    assert "not at rest" not in capsys.readouterr().err  # but not on rest: it agrees
