"""The ULog fast path (``readers/_fast_ulog.py``) against pyulog: the same topic data
(every field, dtype and value) and info on the real PX4 logs, the same runs bit for
bit on real, committed, generated and cut logs, pyulog (with a note) where the fast
path does not cover a log, and no crash on bad bytes."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

import biglogkit
from fastkit import assert_same_runs, corpus_dir
from gyrotherm import RunFileError
from gyrotherm.readers._common import FALLBACK_KEY
from gyrotherm.readers._fast_common import Fallback
from gyrotherm.readers._fast_ulog import load
from gyrotherm.readers._ulog import TOPICS, read_ulog

DATA = Path(__file__).parents[1] / "data"
COMMITTED = [DATA / "px4_sample_log_small_imu.ulg", DATA / "px4_two_gyros.ulg"]


def real_ulogs() -> list[Path]:
    real = corpus_dir()
    return sorted(real.glob("px4/*.ulg")) if real else []


def same_reading(p: Path) -> None:
    """read_ulog on both paths: the same runs (the note only when the fast path
    refused), or the same error."""
    try:
        slow = read_ulog(p, fast=False)
    except RunFileError as exc:
        with pytest.raises(RunFileError) as fast_exc:
            read_ulog(p)
        assert str(fast_exc.value) == str(exc)
        return
    try:
        load(p, TOPICS)
        note = False
    except Fallback:
        note = True
    assert_same_runs(read_ulog(p), slow, note=note)


@pytest.mark.parametrize("path", real_ulogs() or [pytest.param(None, marks=pytest.mark.skip(
    reason="real-log corpus not found (GYROTHERM_REALLOGS)"))],
    ids=lambda p: getattr(p, "name", ""))
def test_topics_equal_pyulogs_on_real_logs(path: Path) -> None:
    """Every field of sensor_gyro, sensor_accel, vehicle_status, actuator_armed
    (names, dtype, values) and the info messages; then the runs."""
    from pyulog import ULog

    with contextlib.redirect_stdout(io.StringIO()):
        ref = ULog(str(path), TOPICS)
    try:
        fast = load(path, TOPICS)
    except Fallback as exc:
        assert "appended" in str(exc) and ref.has_data_appended
        same_reading(path)
        return
    assert [(d.name, d.multi_id) for d in fast.data_list] == \
        [(d.name, d.multi_id) for d in ref.data_list]
    for f, r in zip(fast.data_list, ref.data_list, strict=True):
        assert list(f.data) == list(r.data)
        for k, v in r.data.items():
            assert f.data[k].dtype == v.dtype and np.array_equal(f.data[k], v, equal_nan=True)
    assert fast.msg_info_dict == ref.msg_info_dict
    assert not ref.file_corruption
    same_reading(path)


def test_committed_and_generated_logs(tmp_path: Path) -> None:
    big = tmp_path / "big.ulg"
    biglogkit.write_ulog(big, 30_000, seed=3)
    for p in [*COMMITTED, big]:
        load(p, TOPICS)  # covered
        same_reading(p)


@pytest.mark.parametrize("source", COMMITTED, ids=lambda p: p.name)
def test_logs_cut_anywhere(tmp_path: Path, source: Path) -> None:
    """Cut inside the definitions, inside a data message, on a boundary: the same
    runs, ``bytes_cut_at_end`` and errors as pyulog with the reader's own count."""
    data = source.read_bytes()
    rng = np.random.default_rng(1)
    p = tmp_path / "cut.ulg"
    for n in sorted({len(data) - 1, len(data) - 2, *rng.integers(16, len(data), 12).tolist()}):
        p.write_bytes(data[:n])
        same_reading(p)


@pytest.mark.parametrize("seed", range(30))
def test_bad_bytes_never_crash(tmp_path: Path, seed: int) -> None:
    rng = np.random.default_rng(seed)
    data = bytearray(COMMITTED[seed % 2].read_bytes())
    for _ in range(int(rng.integers(1, 6))):
        k = int(rng.integers(0, len(data)))
        data[k] = int(rng.integers(0, 256))
    p = tmp_path / "bad.ulg"
    p.write_bytes(bytes(data))
    try:
        load(p, TOPICS)
    except Fallback:
        pass
    try:
        runs = read_ulog(p)
    except RunFileError:
        return
    assert runs


def test_a_log_pyulog_must_read_carries_a_note(tmp_path: Path) -> None:
    """An unknown message type in the data section (pyulog's corruption handling)."""
    data = bytearray(COMMITTED[1].read_bytes())
    fast = load(COMMITTED[1], TOPICS)
    assert fast.bytes_cut_at_end == 0
    end = len(data)
    data += bytes([3, 0, ord("X"), 1, 2, 3])  # size 3, type 'X'
    p = tmp_path / "x.ulg"
    p.write_bytes(bytes(data))
    with pytest.raises(Fallback, match="message type"):
        load(p, TOPICS)
    runs = read_ulog(p)
    assert "message type" in runs[0].metadata[FALLBACK_KEY] and end
    assert_same_runs(runs, read_ulog(p, fast=False), note=True)


def _pyulog(p: Path) -> object:
    from pyulog import ULog

    with contextlib.redirect_stdout(io.StringIO()):
        return ULog(str(p), TOPICS)


def test_fields_decode_what_the_reader_reads(tmp_path: Path) -> None:
    """``fields`` limits the columns to those named (``a|b``: the first the topic
    has), each equal to pyulog's; a topic lacking one gets every field."""
    import ulogkit

    two = ulogkit.write(tmp_path / "two.ulg", ulogkit.two_gyros())
    fast = load(two, TOPICS, fields={"sensor_gyro": ("nope|timestamp_sample|timestamp", "x"),
                                     "sensor_accel": ("x", "missing")})
    ref = _pyulog(two)
    for f, r in zip(fast.data_list, ref.data_list, strict=True):  # type: ignore[attr-defined]
        want = ["timestamp_sample", "x"] if f.name == "sensor_gyro" else list(r.data)
        assert list(f.data) == want
        for k in want:
            assert f.data[k].dtype == r.data[k].dtype and np.array_equal(f.data[k], r.data[k])


def test_a_subscription_added_after_data_began(tmp_path: Path) -> None:
    """A second batch of ``A`` messages after data of the first (PX4 adds a topic when
    it first publishes), topics interleaved (no stride), a ``D`` byte inside payloads:
    every field as pyulog's, and the same runs."""
    import struct

    import ulogkit
    from ulogkit import ACCEL_FIELDS, GYRO_FIELDS, _msg, _pack

    rng = np.random.default_rng(7)
    out = ulogkit.header_and_definitions()
    out += _msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    t_us = 1_000_000
    for k in range(400):
        if k == 150:  # the accel appears later, with msg_id 1
            out += _msg(b"A", struct.pack("<BH", 0, 1) + b"sensor_accel")
        t_us += int(rng.integers(900, 1100))
        x = 785.0 if k % 7 == 0 else float(rng.normal())  # float32 bytes 00 40 44 44: "DD"
        out += _msg(b"D", struct.pack("<H", 0) + _pack(
            GYRO_FIELDS, [t_us, t_us - 50, 2, x, 0.25, -0.5, 30.0 + k / 100, 0]))
        if k >= 150 and rng.random() < 0.6:
            out += _msg(b"D", struct.pack("<H", 1) + _pack(
                ACCEL_FIELDS, [t_us + 10, t_us, 1, 0.0, 0.1, 9.8, 30.0, 0]))
    p = ulogkit.write(tmp_path / "late.ulg", out)
    fast, ref = load(p, TOPICS), _pyulog(p)
    assert [(d.name, len(d.data["timestamp"])) for d in fast.data_list] == \
        [(d.name, len(d.data["timestamp"])) for d in ref.data_list]  # type: ignore[attr-defined]
    assert [d.name for d in fast.data_list] == ["sensor_accel", "sensor_gyro"]
    for f, r in zip(fast.data_list, ref.data_list, strict=True):  # type: ignore[attr-defined]
        for k, v in r.data.items():
            assert np.array_equal(f.data[k], v)
    same_reading(p)
