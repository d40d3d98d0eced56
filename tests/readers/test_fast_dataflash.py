"""The DataFlash fast path (numpy index, ``readers/_fast_dataflash.py``) against
pymavlink: the same index on the real ArduPilot logs, the same runs bit for bit on
generated logs, pymavlink (with a note) where the fast path does not cover a log, and
no crash on bad bytes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import biglogkit
import dataflashkit
from fastkit import assert_same_runs, corpus_dir
from gyrotherm import RunFileError
from gyrotherm.readers._common import FALLBACK_KEY
from gyrotherm.readers._dataflash import read_dataflash
from gyrotherm.readers._fast_dataflash import Fallback, open_fast


def real_dataflash() -> list[Path]:
    real = corpus_dir()
    return sorted(real.glob("ardupilot/*.bin")) if real else []


@pytest.mark.parametrize("path", real_dataflash() or [pytest.param(None, marks=pytest.mark.skip(
    reason="real-log corpus not found (GYROTHERM_REALLOGS)"))],
    ids=lambda p: getattr(p, "name", ""))
def test_fast_index_equals_pymavlinks_on_real_logs(path: Path) -> None:
    """Every message type's offsets, the names and each format's struct, columns and
    multipliers: what the reader takes from pymavlink's index."""
    from pymavlink.DFReader import DFReader_binary

    fast = open_fast(path)
    ref = DFReader_binary(str(path))
    try:
        assert fast.offsets is not None
        for t in range(256):
            assert np.array_equal(fast.offsets[t], np.asarray(ref.offsets[t], dtype=np.int64))
        assert fast.name_to_id == ref.name_to_id
        assert sorted(fast.formats) == sorted(ref.formats)
        for t, f in ref.formats.items():
            g = fast.formats[t]
            assert (g.name, g.len, g.msg_struct, g.columns, g.msg_mults) == \
                (f.name, f.len, f.msg_struct, f.columns, f.msg_mults)
        assert sum(len(o) for o in fast.offsets) > 100
    finally:
        fast.close()
        ref.close()


def _variants(tmp_path: Path) -> list[Path]:
    two = dataflashkit.two_imus()
    out = {"two_imus.bin": two, "legacy.bin": dataflashkit.legacy(),
           "cut_in_gyr.bin": two[:-20], "cut_in_imu.bin": two[:-40]}
    for name, data in out.items():
        (tmp_path / name).write_bytes(data)
    big = tmp_path / "big.bin"
    biglogkit.write_dataflash(big, 30_000, seed=3)
    return [tmp_path / n for n in out] + [big]


def test_fast_path_equals_pymavlink_bit_for_bit_on_generated_logs(tmp_path: Path) -> None:
    for p in _variants(tmp_path):
        open_fast(p).close()  # covered by the fast path: no Fallback
        assert_same_runs(read_dataflash(p), read_dataflash(p, fast=False))


def test_false_headers_inside_payloads_are_stepped_over(tmp_path: Path) -> None:
    """Rates whose float32 bytes hold ``A3 95``: candidates inside messages."""
    p = tmp_path / "false.bin"
    biglogkit.write_dataflash(p, 2_000, seed=4)
    data = bytearray(p.read_bytes())
    fake = np.frombuffer(b"\xa3\x95\x80\x00", dtype="<f4")[0]  # looks like an FMT header
    fast = open_fast(p)
    assert fast.offsets is not None
    imu = fast.offsets[dataflashkit.IMU.type]
    fast.close()
    for k in range(0, len(imu), 7):  # GyrY of every 7th message (body offset 3 + 9 + 4)
        data[imu[k] + 16:imu[k] + 20] = fake.tobytes()
    p.write_bytes(bytes(data))
    open_fast(p).close()
    assert_same_runs(read_dataflash(p), read_dataflash(p, fast=False))


def test_a_corrupt_region_is_read_by_pymavlink_with_a_note(tmp_path: Path) -> None:
    data = dataflashkit.two_imus()
    fmt_end = data.index(b"\xa3\x95\x81")  # the first IMU message
    p = tmp_path / "corrupt.bin"
    p.write_bytes(data[:fmt_end] + b"\x00garbage\x00" + data[fmt_end:])
    with pytest.raises(Fallback, match="corrupt region"):
        open_fast(p)
    runs = read_dataflash(p)
    assert "corrupt region" in runs[0].metadata[FALLBACK_KEY]
    assert_same_runs(runs, read_dataflash(p, fast=False), note=True)


@pytest.mark.parametrize("seed", range(40))
def test_bad_bytes_never_crash(tmp_path: Path, seed: int) -> None:
    """Random damage to a valid log (bytes flipped, cut, FMT lengths of 0–2):
    a run list or a RunFileError, never another exception."""
    rng = np.random.default_rng(seed)
    data = bytearray(dataflashkit.two_imus())
    for _ in range(int(rng.integers(1, 6))):
        k = int(rng.integers(0, len(data)))
        data[k] = int(rng.integers(0, 256))
    if seed % 4 == 0:  # an FMT's Length byte (offset 4 of each 89-byte FMT) made tiny
        fmt = int(rng.integers(0, 3))
        data[fmt * 89 + 4] = int(rng.integers(0, 3))
    if seed % 3 == 0:
        data = data[:int(rng.integers(3, len(data)))]
    p = tmp_path / "bad.bin"
    p.write_bytes(bytes(data))
    try:
        open_fast(p).close()
    except Fallback:
        pass
    try:
        read_dataflash(p)
    except RunFileError:
        pass
