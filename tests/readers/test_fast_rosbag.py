"""The MCAP fast path (``readers/_fast_mcap.py``, ``_fast_cdr.py``, ``_fast_rosbag.py``)
against rosbags: the same runs bit for bit on bags rosbags writes (frame ids of every
alignment, zero stamps, absent vectors, out-of-order log times, zstd chunks, an hour's
worth of rows in small), the same messages as the ``mcap`` library on the real ROS 2
corpus, rosbags (with a note) where the fast path does not cover a file, and no crash
on bad bytes."""

from __future__ import annotations

import math
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

import biglogkit
import rosbagkit
from fastkit import assert_same_runs, corpus_dir
from gyrotherm import RunFileError
from gyrotherm.readers._common import FALLBACK_KEY
from gyrotherm.readers._fast_common import Fallback
from gyrotherm.readers._fast_mcap import Source, checked, load, plan, summary
from gyrotherm.readers._fast_rosbag import gather
from gyrotherm.readers._rosbag import read_rosbag

IMU, TEMP = rosbagkit.IMU, rosbagkit.TEMPERATURE
T0 = rosbagkit.T0_NS


def write_mcap(path: Path, topics: dict[str, str], msgs: Sequence[tuple[str, int, bytes]],
               *, zstd: bool = False) -> Path:
    """A plain ``.mcap`` file written by rosbags (chunked, indexed)."""
    with tempfile.TemporaryDirectory() as tmp:
        w = Writer(Path(tmp) / "bag", version=9, storage_plugin=StoragePlugin.MCAP)
        if zstd:
            w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with w:
            conns = {t: w.add_connection(t, m, typestore=rosbagkit.STORE)
                     for t, m in topics.items()}
            for topic, ns, data in msgs:
                w.write(conns[topic], ns, data)
        next((Path(tmp) / "bag").glob("*.mcap")).replace(path)
    return path


def awkward_messages(n: int = 600) -> list[tuple[str, int, bytes]]:
    """Two IMU topics, frame ids of lengths 0–9 (every CDR alignment), zero stamps,
    rates/accelerations marked absent, NaN, repeated stamps, log times out of order."""
    rng = np.random.default_rng(5)
    frames = ["", "a", "imu", "imu_lin", "imu_link", "imu_link9", "ÿmu"]
    msgs: list[tuple[str, int, bytes]] = []
    for k in range(n):
        ns = T0 + k * 1_000_000
        log = ns + int(rng.integers(-3_000_000, 3_000_000))  # not in time order
        topic = ("/imu0/data", "/imu1/data")[k % 2]
        stamp = 0 if k % 37 == 0 else ns - (ns % 2_000_000 if k % 11 == 0 else 0)
        w = None if k % 13 == 0 else tuple(rng.normal(size=3) * (math.nan if k % 29 == 0 else 1))
        a = None if k % 17 == 0 else tuple(rng.normal(size=3))
        frame = frames[(k // 2) % len(frames)] if topic == "/imu1/data" else "imu0"
        msgs.append((topic, log, rosbagkit.imu_msg(stamp, frame, w, a)))
        if k % 10 == 0:
            for ns_t, t in (("/imu0/temperature", 30.0 + k / 100), ("/imu1/temperature", 50.0)):
                msgs.append((ns_t, log, rosbagkit.temperature_msg(0 if k == 20 else ns,
                                                                  "t", t)))
    return msgs


TOPICS = {"/imu0/data": IMU, "/imu1/data": IMU, "/imu0/temperature": TEMP,
          "/imu1/temperature": TEMP}


@pytest.mark.parametrize(("zstd", "n"), [(False, 600), (True, 600), (False, 12_000)],
                         ids=["plain", "zstd", "chunks"])
def test_fast_path_equals_rosbags_bit_for_bit(tmp_path: Path, zstd: bool, n: int) -> None:
    """``chunks``: about 5 MB, so several chunks, decoded in several groups, with log
    times out of order across chunk boundaries."""
    p = write_mcap(tmp_path / "awkward.mcap", TOPICS, awkward_messages(n), zstd=zstd)
    gather(p, ["/imu0/data", "/imu1/data"], ["/imu0/temperature", "/imu1/temperature"])
    fast = read_rosbag(p)
    assert len(fast) == 8  # imu0 + seven frame ids of imu1
    assert_same_runs(fast, read_rosbag(p, fast=False))
    for topic in ("/imu0/data", "/imu1/data"):
        assert_same_runs(read_rosbag(p, imu_topic=topic),
                         read_rosbag(p, imu_topic=topic, fast=False))


def test_generated_long_log_and_committed_fixture(tmp_path: Path) -> None:
    big = tmp_path / "big.mcap"
    biglogkit.write_mcap(big, 30_000, seed=3)
    fixture = Path(__file__).parents[1] / "data" / "imu.mcap"
    for p in (big, fixture):
        assert_same_runs(read_rosbag(p), read_rosbag(p, fast=False))


def real_mcaps() -> list[Path]:
    real = corpus_dir()
    return sorted(real.glob("ros2/*.mcap")) if real else []


@pytest.mark.parametrize("path", real_mcaps() or [pytest.param(None, marks=pytest.mark.skip(
    reason="real-log corpus not found (GYROTHERM_REALLOGS)"))],
    ids=lambda p: getattr(p, "name", ""))
def test_container_equals_the_mcap_librarys_on_real_files(path: Path) -> None:
    """Every channel's messages (payload bytes, log time, order within the channel):
    the fast path's container reading against the ``mcap`` library's."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        ref: dict[int, list[tuple[int, bytes]]] = {}
        for _, channel, message in make_reader(fh).iter_messages(log_time_order=False):
            ref.setdefault(channel.id, []).append((message.log_time, bytes(message.data)))
    got: dict[int, list[tuple[int, bytes]]] = {}
    with path.open("rb") as fh:
        src = Source(fh)
        s = summary(src)
        for chunk in s.chunks:
            q = plan(src, chunk, sorted(s.channels))
            for cid, indexed in load(src, [q]) if q else []:
                m = checked(cid, [indexed])
                got.setdefault(cid, []).extend(
                    (int(t), bytes(m.buf[a:a + n]))
                    for t, a, n in zip(m.log_time, m.start, m.size, strict=True))
    assert got == ref and sum(len(v) for v in got.values()) > 0


def test_what_the_fast_path_does_not_cover_is_read_by_rosbags_with_a_note(
        tmp_path: Path) -> None:
    """A frame id ending in NUL bytes (rosbags keeps them; numpy's S strings would not)."""
    msgs = [("/imu/data", T0 + k, rosbagkit.imu_msg(T0 + k, "imu\0", (0.1, 0.2, 0.3), None))
            for k in range(5)] + [("/imu/temperature", T0, rosbagkit.temperature_msg(T0, "", 30))]
    p = write_mcap(tmp_path / "nul.mcap", {"/imu/data": IMU, "/imu/temperature": TEMP}, msgs)
    with pytest.raises(Fallback, match="NUL"):
        gather(p, ["/imu/data"], ["/imu/temperature"])
    runs = read_rosbag(p)
    assert "NUL" in runs[0].metadata[FALLBACK_KEY]
    assert_same_runs(runs, read_rosbag(p, fast=False), note=True)


@pytest.mark.parametrize("seed", range(30))
def test_bad_bytes_never_crash(tmp_path: Path, seed: int) -> None:
    """Bytes flipped anywhere (records, indexes, CDR, summary), or the file cut: runs
    or a RunFileError, never another exception."""
    rng = np.random.default_rng(seed)
    good = tmp_path / "good.mcap"
    write_mcap(good, TOPICS, awkward_messages(60))
    data = bytearray(good.read_bytes())
    for _ in range(int(rng.integers(1, 8))):
        k = int(rng.integers(0, len(data)))
        data[k] = int(rng.integers(0, 256))
    if seed % 5 == 0:
        data = data[:int(rng.integers(0, len(data)))]
    p = tmp_path / "bad.mcap"
    p.write_bytes(bytes(data))
    try:
        gather(p, ["/imu0/data"], ["/imu0/temperature"])
    except Fallback:
        pass
    try:
        read_rosbag(p)
    except RunFileError:
        pass
