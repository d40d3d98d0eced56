"""candump logs as runs: round trip through the frame encoder and the log format, the
latest-temperature rule, the time origin, rejected frames counted by reason, errors.

Truth: runs built by hand (or by the independent synthetic generator), encoded by
:func:`gyrotherm.sim.frames_from_run`; the DBC's resolution bounds the error
(rate 0.002 °/s and temperature 0.01 °C per LSB, rounded: half an LSB).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from gyrotherm import RunFileError
from gyrotherm.analysis import SynthConfig, synth_runs
from gyrotherm.codecs import (
    FrameEncoder,
    RateSample,
    Run,
    TemperatureSample,
    format_candump_line,
    write_candump,
    write_run,
)
from gyrotherm.codecs._candump_run import POWER_ON_LIMIT_S, is_candump_log, run_from_candump
from gyrotherm.sim import frames_from_run

RATE_HALF_LSB = 0.001 + 1e-9
TEMP_HALF_LSB = 0.005 + 1e-9
STAMP_ERR = 1e-6  # the log keeps microseconds; float64 at 1.7e9 s resolves 2.4e-7 s


def _three_axis_run(n: int = 400, rate_hz: float = 10.0) -> Run:
    rng = np.random.default_rng(4)
    t = np.arange(n) / rate_hz
    return Run(
        name="hand",
        time_s=t,
        temperature_c=20.0 + 0.02 * t + rng.normal(0, 0.05, n),
        rates_dps={"x": rng.normal(0.3, 0.05, n), "y": rng.normal(-1.2, 0.05, n),
                   "z": rng.normal(0.0, 0.05, n)},
    )


def _log(run: Run, path: Path, *, period_s: float = 0.0, t0_s: float = 0.0) -> list[str]:
    frames = frames_from_run(run, encoder=FrameEncoder(), temperature_period_s=period_s, t0_s=t0_s)
    write_candump(path, frames)
    return path.read_text().splitlines()


def test_round_trip_of_a_three_axis_run(tmp_path: Path) -> None:
    run = _three_axis_run()
    log = tmp_path / "bench.log"
    _log(run, log)
    back = run_from_candump(log)
    assert back.name == "bench" and back.source == str(log)
    assert back.axes == ("x", "y", "z")
    assert len(back) == len(run)
    assert np.max(np.abs(back.time_s - run.time_s)) <= STAMP_ERR
    for a in "xyz":
        assert np.max(np.abs(back.rates_dps[a] - run.rates_dps[a])) <= RATE_HALF_LSB
    assert np.max(np.abs(back.temperature_c - run.temperature_c)) <= TEMP_HALF_LSB
    md = back.metadata
    assert md["time_origin"] == "log" and md["frames"] == str(2 * len(run))
    assert md["frames_rejected_crc_mismatch"] == "0" and md["counter_jumps"] == "0"
    assert md["rows_before_first_temperature"] == "0"
    assert back.sha256 == hashlib.sha256(log.read_bytes()).hexdigest()


def test_round_trip_of_a_synthetic_run_drops_the_zero_filled_axes(tmp_path: Path) -> None:
    runs, _ = synth_runs(SynthConfig(duration_s=600.0, rate_hz=10.0), n_runs=1, seed=3)
    run = runs[0]
    log = tmp_path / "synth.log"
    _log(run, log)
    back = run_from_candump(log, name="s")
    assert back.name == "s" and back.axes == ("x",)  # y, z were sent as 0 °/s
    assert back.metadata["axes_dropped_all_zero"] == "y,z"
    assert np.max(np.abs(back.rates_dps["x"] - run.rates_dps["x"])) <= RATE_HALF_LSB
    assert np.max(np.abs(back.temperature_c - run.temperature_c)) <= TEMP_HALF_LSB
    assert np.max(np.abs(back.time_s - run.time_s)) <= STAMP_ERR


def test_temperature_is_the_latest_sample_at_or_before_each_row(tmp_path: Path) -> None:
    # 10 Hz rows, temperature frames once per 1 s slot (sent with the slot's first row):
    # row i carries the reading of row 10·floor(i/10)
    n = 45
    t = np.arange(n) / 10.0
    temp = 20.0 + 0.01 * np.arange(n)
    run = Run(name="slots", time_s=t, temperature_c=temp, rates_dps={"x": np.full(n, 0.5)})
    log = tmp_path / "slots.log"
    lines = _log(run, log, period_s=1.0)
    assert len(lines) == n + 5
    back = run_from_candump(log)
    expected = 20.0 + 0.01 * (10 * (np.arange(n) // 10))
    assert np.allclose(back.temperature_c, expected, atol=1e-9)
    assert back.metadata["temperature_samples"] == "5"


def test_wall_clock_timestamps_start_at_the_first_frame(tmp_path: Path) -> None:
    run = _three_axis_run(50)
    log = tmp_path / "wall.log"
    _log(run, log, t0_s=1_700_000_000.0)
    back = run_from_candump(log)
    assert back.metadata["time_origin"] == "first frame"
    assert back.metadata["time_origin_s"] == "1700000000.000000"
    assert np.max(np.abs(back.time_s - run.time_s)) <= STAMP_ERR
    # a log already on time since power-on keeps its origin (a warm-up stays in place)
    late = tmp_path / "late.log"
    _log(run, late, t0_s=3600.0)
    back = run_from_candump(late)
    assert back.metadata["time_origin"] == "log"
    assert back.time_s[0] == pytest.approx(3600.0, abs=STAMP_ERR)
    assert POWER_ON_LIMIT_S == 1e6


def test_rejected_frames_are_counted_by_reason_never_silently(tmp_path: Path) -> None:
    run = _three_axis_run(100)
    log = tmp_path / "bad.log"
    lines = _log(run, log)
    # lines alternate temperature (even) / rate (odd) frames of row i = line // 2
    rate_lines = [i for i, s in enumerate(lines) if " 120#" in s]
    assert len(rate_lines) == 100
    corrupt = rate_lines[10:13]  # rows 10, 11, 12: flip a data bit, the CRC no longer fits
    for i in corrupt:
        head, data = lines[i].split("#")
        lines[i] = f"{head}#{int(data[0], 16) ^ 1:X}{data[1:]}"
    # insert from the back so that the indices above stay valid
    back_stamp = float(lines[rate_lines[60]][1:18]) - 0.05
    old = FrameEncoder().encode_rate(RateSample(back_stamp, 9.0, 9.0, 9.0))
    lines.insert(rate_lines[60] + 1, format_candump_line(old))  # a stamp going backwards
    # the rate frame of row 40 logged twice: the second is a duplicate_time
    lines.insert(rate_lines[40] + 1, lines[rate_lines[40]])
    extra = [
        "(0000000000.050000) can0 7A0#0102",  # another device: unknown_id
        "(0000000000.060000) can0 120#0102",  # rate id, 2 bytes: wrong_length
        "(0000000000.070000) can0 20000080#0000000000000000",  # error frame: decode_error
    ]
    lines = lines[:2] + extra + lines[2:]
    log.write_text("\n".join(lines) + "\n")
    back = run_from_candump(log)
    md = back.metadata
    assert md["frames_rejected_crc_mismatch"] == "3"
    assert md["frames_rejected_unknown_id"] == "1"
    assert md["frames_rejected_wrong_length"] == "1"
    assert md["frames_rejected_decode_error"] == "1"
    assert md["frames_rejected_duplicate_time"] == "1"
    assert md["frames_rejected_time_backwards"] == "1"
    # counters: after the CRC failures (row 13), the repeated frame, the stray frame
    # and the frame after it
    assert int(md["counter_jumps"]) == 4
    assert md["frames"] == str(len(lines))
    assert len(back) == 100 - 3
    kept = np.delete(np.arange(100), [10, 11, 12])
    assert np.max(np.abs(back.time_s - run.time_s[kept])) <= STAMP_ERR
    assert np.max(np.abs(back.rates_dps["x"] - run.rates_dps["x"][kept])) <= RATE_HALF_LSB


def test_rows_before_the_first_temperature_are_dropped_and_status_counted(
        tmp_path: Path) -> None:
    enc = FrameEncoder()
    frames = [enc.encode_rate(RateSample(0.1 * i, 1.0, 2.0, 3.0)) for i in range(3)]
    frames.append(enc.encode_temperature(TemperatureSample(0.25, 30.0, status=4)))
    frames += [enc.encode_rate(RateSample(0.1 * i, 1.0, 2.0, 3.0)) for i in range(3, 6)]
    frames.append(enc.encode_temperature(TemperatureSample(0.5, 31.0)))
    log = tmp_path / "late-temp.log"
    write_candump(log, frames)
    back = run_from_candump(log)
    assert back.metadata["rows_before_first_temperature"] == "3"
    assert back.metadata["temperature_status_nonzero"] == "1"
    assert np.allclose(back.time_s, [0.3, 0.4, 0.5])
    assert back.temperature_c.tolist() == [30.0, 30.0, 31.0]  # 0.5 s: at or before


def test_errors_name_the_file_and_the_problem(tmp_path: Path) -> None:
    enc = FrameEncoder()
    only_temp = tmp_path / "only-temp.log"
    write_candump(only_temp, [enc.encode_temperature(TemperatureSample(1.0, 20.0))])
    with pytest.raises(RunFileError, match=r"only-temp\.log: candump log has no valid rate "
                       r"frame \(message 'GyroRate', id 0x120\)"):
        run_from_candump(only_temp)
    only_rate = tmp_path / "only-rate.log"
    good = format_candump_line(enc.encode_rate(RateSample(1.0, 0.0, 0.0, 0.0)))
    only_rate.write_text(f"{good}\n(0000000002.000000) can0 121#{'00' * 8}\n")
    with pytest.raises(RunFileError, match=r"no valid temperature frame .*crc_mismatch: 1"):
        run_from_candump(only_rate)
    early = tmp_path / "early.log"
    write_candump(early, [enc.encode_rate(RateSample(1.0, 0.0, 0.0, 0.0)),
                          enc.encode_temperature(TemperatureSample(2.0, 20.0))])
    with pytest.raises(RunFileError, match="precede the first temperature"):
        run_from_candump(early)
    garbled = tmp_path / "garbled.log"
    garbled.write_text(f"{good}\n\nnot a frame\n")
    with pytest.raises(RunFileError, match=r"garbled\.log:3: "):
        run_from_candump(garbled)
    with pytest.raises(RunFileError, match="cannot open candump log"):
        run_from_candump(tmp_path / "missing.log")


def test_candump_logs_are_recognised_by_content(tmp_path: Path) -> None:
    run = _three_axis_run(20)
    csv_named_log = write_run(run, tmp_path / "run.log")
    assert not is_candump_log(csv_named_log)
    log_named_csv = tmp_path / "frames.csv"
    lines = _log(run, log_named_csv)
    assert is_candump_log(log_named_csv)
    padded = tmp_path / "padded"
    padded.write_text("\n  \n" + "\n".join(lines) + "\n")
    assert is_candump_log(padded)
    (tmp_path / "empty").write_text("\n\n")
    assert not is_candump_log(tmp_path / "empty")
    assert not is_candump_log(tmp_path / "missing")
