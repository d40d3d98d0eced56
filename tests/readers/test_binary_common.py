"""Helpers of the binary-log readers: hold, interpolation, sort/dedupe, hashing, make_run."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from gyrotherm import RunFileError
from gyrotherm.readers._common import (
    hold_previous,
    interpolate,
    make_run,
    sha256_of,
    sort_unique,
)


def test_hold_previous_takes_latest_at_or_before() -> None:
    got = hold_previous(np.array([1.0, 2.0, 3.0]), np.array([10.0, 20.0, 30.0]),
                        np.array([0.5, 1.0, 1.5, 2.0, 9.0]))
    np.testing.assert_array_equal(got, [np.nan, 10.0, 10.0, 20.0, 30.0])


def test_interpolate_holds_one_period_beyond_the_ends_then_nan() -> None:
    got = interpolate(np.array([1.0, 2.0, 3.0]), np.array([0.0, 1.0, 4.0]),
                      np.array([-0.5, 0.5, 1.5, 2.5, 3.9, 4.5]))
    np.testing.assert_array_equal(got, [np.nan, 0.0, 0.5, 2.5, 4.0, np.nan])


def test_sort_unique_counts_reordered_and_repeats() -> None:
    rows, reordered, dupes = sort_unique(np.array([1.0, 3.0, 2.0, 3.0, 4.0]))
    assert list(rows) == [0, 2, 1, 4] and (reordered, dupes) == (1, 1)


def test_sha256_of_file_and_directory(tmp_path: Path) -> None:
    f = tmp_path / "a.bin"
    f.write_bytes(b"abc")
    assert sha256_of(f) == hashlib.sha256(b"abc").hexdigest()
    d = tmp_path / "bag"
    d.mkdir()
    (d / "x").write_bytes(b"1")
    first = sha256_of(d)
    (d / "x").write_bytes(b"2")
    assert sha256_of(d) != first


def test_make_run_drops_nonfinite_and_names_what_is_missing(tmp_path: Path) -> None:
    p = tmp_path / "log.bin"
    run = make_run(path=p, device="IMU[0]", where="message 'IMU'",
                   time_s=np.array([0.0, 1.0, 2.0]), temperature_c=np.array([20.0, np.nan, 21.0]),
                   rates={"x": np.array([0.0, 1.0, 2.0])}, rate_to_dps=2.0,
                   accel_mps2={"x": np.array([1.0, 1.0, np.nan])}, metadata={"a": "b"},
                   sha256="0" * 64)
    assert run.name == "log:IMU[0]" and run.metadata["rows_nonfinite_dropped"] == "1"
    np.testing.assert_array_equal(run.rates_dps["x"], [0.0, 4.0])
    assert run.extra == {}  # accelerometer not present on every kept row: left out
    assert run.metadata["accel_rows_missing"] == "1"
    with pytest.raises(RunFileError, match=r"log\.bin: message 'IMU': no temperature in 3"):
        make_run(path=p, device="IMU[0]", where="message 'IMU'",
                 time_s=np.arange(3.0), temperature_c=np.full(3, np.nan),
                 rates={"x": np.zeros(3)}, rate_to_dps=1.0, metadata={}, sha256="")
