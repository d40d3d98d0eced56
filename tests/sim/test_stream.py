"""``gyrotherm sim stream``: frame streams from runs and logs, the paced player, the CLI.

Truth: the shipped DBC's documented layout (frames assembled by hand with a
bitwise CRC-8/SAE-J1850 written here), the run's own values decoded back with
``FrameDecoder``, ``FrameEncoder`` row by row for the vectorised packer,
schedules computed by hand against a fake clock, and python-can's own
socketcand client for the CLI.
"""

from __future__ import annotations

import argparse
import os
import queue
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
import pytest

from gyrotherm import ConfigError, DecodeError, RunFileError
from gyrotherm.bus import FrameSink
from gyrotherm.cli._stream import main as stream_main
from gyrotherm.cli._stream import register
from gyrotherm.codecs import Run
from gyrotherm.codecs._can import FrameDecoder, RateSample, TemperatureSample
from gyrotherm.codecs._canenc import FrameEncoder
from gyrotherm.sim._experiment import chamber_runs
from gyrotherm.sim._stream import (
    CandumpSink,
    frames_from_candump,
    frames_from_run,
    play,
)
from streamkit import USER_DBC, USER_SIGNAL_MAP

TIMEOUT_S = 30.0
RATE_ID, TEMP_ID = 0x120, 0x121
RATE_LSB, TEMP_LSB = 0.002, 0.01
ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-c", "from gyrotherm.cli._stream import main; raise SystemExit(main())"]


def crc8_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850 from its definition (poly 0x1D, init 0xFF, xorout 0xFF)."""
    r = 0xFF
    for b in data:
        r ^= b
        for _ in range(8):
            r = ((r << 1) ^ 0x1D) & 0xFF if r & 0x80 else (r << 1) & 0xFF
    return r ^ 0xFF


def make_run(
    time_s: list[float],
    temperature_c: list[float],
    x: list[float],
    *,
    metadata: dict[str, str] | None = None,
) -> Run:
    n = len(time_s)
    return Run(
        name="hand",
        time_s=np.array(time_s),
        temperature_c=np.array(temperature_c),
        rates_dps={"x": np.array(x), "y": np.zeros(n), "z": -np.array(x)},
        metadata=metadata or {},
    )


@pytest.fixture(scope="module")
def short_run() -> Run:
    """441 rows at 2 Hz: 60 s hold, 100 s ramp (heating 1.6667 min), 60 s hold."""
    return chamber_runs([100 / 60], seed=7, rate_hz=2.0, hold_s=60.0)[0]


class ListSink(FrameSink):
    def __init__(self, on_send: object = None) -> None:
        self.frames: list[can.Message] = []
        self._on_send = on_send
        self._closed = False

    @property
    def is_shutdown(self) -> bool:
        return self._closed

    def send(self, msg: can.Message, timeout_s: float | None = None) -> None:
        self.frames.append(msg)
        if callable(self._on_send):
            self._on_send(msg)

    def shutdown(self) -> None:
        self._closed = True


class FakeTime:
    """A clock and a stop event whose ``wait`` advances the clock instead of sleeping."""

    def __init__(self, start_s: float, *, oversleep_s: float = 0.0) -> None:
        self.now = start_s
        self.waits: list[float] = []
        self.flag = False
        self.oversleep_s = oversleep_s
        self.stop_on_wait = False

    def clock(self) -> float:
        return self.now

    def is_set(self) -> bool:
        return self.flag

    def wait(self, timeout: float | None = None) -> bool:
        assert timeout is not None and timeout > 0
        self.waits.append(timeout)
        if self.stop_on_wait:
            self.flag = True
            return True
        self.now += timeout + self.oversleep_s
        return False


def msg_at(ts: float, arb: int = RATE_ID) -> can.Message:
    return can.Message(timestamp=ts, arbitration_id=arb, is_extended_id=False, data=bytes(8))


# ------------------------------------------------------------------- frames from runs


def test_hand_computed_first_frames() -> None:
    run = make_run([0.0, 0.5], [25.0, -0.01], [0.002, -65.534])
    frames = list(frames_from_run(run, encoder=FrameEncoder(), t0_s=10.0))
    # temperature 25.00 degC = 2500 = 0x09C4 LE; status 0; counter 0; reserved 0
    t0 = bytes.fromhex("C409000000000000")[:7]
    # rates x = 1 LSB, y = 0, z = -1 LSB (0xFFFF); counter 0 in the low nibble of byte 6
    r0 = bytes.fromhex("01000000FFFF00")
    # row 1: temperature -1 LSB, counter 1 (bits 24..27); x = -32767 (0x8001), z = +32767
    t1 = bytes.fromhex("FFFF0001000000")
    r1 = bytes.fromhex("0180_0000_FF7F_01".replace("_", ""))
    expected = [(TEMP_ID, t0, 10.0), (RATE_ID, r0, 10.0), (TEMP_ID, t1, 10.5), (RATE_ID, r1, 10.5)]
    assert [(m.arbitration_id, bytes(m.data), m.timestamp) for m in frames] == [
        (arb, body + bytes([crc8_j1850(body)]), ts) for arb, body, ts in expected
    ]
    assert not any(m.is_extended_id or m.is_fd for m in frames)


def test_run_decodes_back_within_half_lsb(short_run: Run) -> None:
    t0 = 1_000.0
    stream = frames_from_run(short_run, encoder=FrameEncoder(), t0_s=t0)
    frames = list(stream)
    decoder = FrameDecoder(on_counter_jump="reject")
    results = [decoder.decode(m) for m in frames]
    rates = [r for r in results if isinstance(r, RateSample)]
    temps = [r for r in results if isinstance(r, TemperatureSample)]
    n = len(short_run)
    assert n == 441 and len(rates) == n and len(frames) == 2 * n  # 2 Hz rows, 10 Hz sensor
    assert all(v == 0 for v in decoder.stats().events.values()), decoder.stats()
    assert stream.saturated == 0
    got = np.array([[r.rate_x_dps, r.rate_y_dps, r.rate_z_dps] for r in rates])
    want = np.column_stack([short_run.rates_dps[a] for a in "xyz"])
    assert np.max(np.abs(got - want)) <= RATE_LSB / 2 + 1e-12
    got_t = np.array([t.temperature_c for t in temps])
    assert np.max(np.abs(got_t - short_run.temperature_c)) <= TEMP_LSB / 2 + 1e-12
    assert [r.counter for r in rates] == [i % 16 for i in range(n)]
    assert [t.counter for t in temps] == [i % 16 for i in range(n)]
    # timestamps: sensor time t0 + time_s, temperature frame first at each row
    assert [r.time_s for r in rates] == (t0 + short_run.time_s).tolist()
    assert [t.time_s for t in temps] == (t0 + short_run.time_s).tolist()
    stamps = [m.timestamp for m in frames]
    assert stamps == sorted(stamps)
    assert [m.arbitration_id for m in frames[:4]] == [TEMP_ID, RATE_ID, TEMP_ID, RATE_ID]


def test_temperature_frame_schedule() -> None:
    time_s = [round(0.1 * i, 10) for i in range(11)]  # 10 Hz rows, 0 .. 1 s
    n = len(time_s)

    def temp_times(run: Run, period: float | None = None) -> list[float]:
        frames = frames_from_run(run, encoder=FrameEncoder(), temperature_period_s=period)
        return [m.timestamp for m in frames if m.arbitration_id == TEMP_ID]

    plain = make_run(time_s, [20.0] * n, [0.0] * n)
    # slots floor(t / 0.25): 0 0 0 1 1 2 2 2 3 3 4 -> first rows of each slot
    assert temp_times(plain, 0.25) == [0.0, 0.3, 0.5, 0.8, 1.0]
    assert temp_times(plain) == time_s  # default 0.1 s: one per 10 Hz row
    assert temp_times(plain, 0.0) == time_s
    from_meta = make_run(time_s, [20.0] * n, [0.0] * n, metadata={"temperature_period_s": "0.5"})
    assert temp_times(from_meta) == [0.0, 0.5, 1.0]
    assert temp_times(from_meta, 1.0) == [0.0, 1.0]  # the argument wins
    bad = make_run(time_s, [20.0] * n, [0.0] * n, metadata={"temperature_period_s": "fast"})
    with pytest.raises(RunFileError, match=r"metadata 'temperature_period_s'.*'fast'"):
        frames_from_run(bad, encoder=FrameEncoder())
    negative = make_run(time_s, [20.0] * n, [0.0] * n, metadata={"temperature_period_s": "-2"})
    with pytest.raises(RunFileError, match=r"temperature_period_s.*>= 0, got -2"):
        frames_from_run(negative, encoder=FrameEncoder())
    with pytest.raises(ConfigError, match="temperature_period_s"):
        frames_from_run(plain, encoder=FrameEncoder(), temperature_period_s=-1.0)


def test_saturation_is_clamped_and_counted() -> None:
    run = make_run([0.0, 1.0, 2.0, 3.0], [20.0, 20.0, 200.0, 20.0], [0.0, 100.0, -np.inf, 1.0])
    frames = list(frames_from_run(run, encoder=FrameEncoder()))
    decoder = FrameDecoder()
    decoded = [decoder.decode(m) for m in frames]
    rates = [d for d in decoded if isinstance(d, RateSample)]
    temps = [d for d in decoded if isinstance(d, TemperatureSample)]
    assert [r.rate_x_dps for r in rates] == pytest.approx([0.0, 65.534, -65.534, 1.0])
    assert [r.rate_z_dps for r in rates] == pytest.approx([0.0, -65.534, 65.534, -1.0])
    assert [t.temperature_c for t in temps] == pytest.approx([20.0, 20.0, 125.0, 20.0])
    assert all(v == 0 for v in decoder.stats().events.values())
    stats = play(frames_from_run(run, encoder=FrameEncoder()), ListSink(), speed=0)
    assert (stats.frames_sent, stats.saturated) == (8, 3)  # rate rows 1, 2; temperature row 2


def test_nan_raises_naming_row_and_signal() -> None:
    run = make_run([0.0, 1.0, 2.0], [20.0, 20.0, 20.0], [0.0, 0.0, np.nan])
    with pytest.raises(DecodeError, match=r"row 2 \(time_s 2\).*RateX.*NaN"):
        frames_from_run(run, encoder=FrameEncoder())


def test_vectorised_payloads_equal_frame_encoder_and_counters_continue() -> None:
    rng = np.random.default_rng(3)
    n = 50
    x = np.r_[rng.normal(0, 30, n - 2), 70.0, -0.001]  # includes a clamp and a round-to-even
    run = make_run(list(0.05 * np.arange(n)), list(rng.normal(40, 60, n)), list(x))
    enc = FrameEncoder()
    for _ in range(5):  # start the rolling counters at 5
        enc.encode_rate(RateSample(0.0, 0, 0, 0))
        enc.encode_temperature(TemperatureSample(0.0, 0.0))
    frames = list(frames_from_run(run, encoder=enc, temperature_period_s=0.0))
    ref = FrameEncoder()
    for _ in range(5):
        ref.encode_rate(RateSample(0.0, 0, 0, 0))
        ref.encode_temperature(TemperatureSample(0.0, 0.0))
    expected = []
    for i in range(n):
        t = float(run.time_s[i])
        expected.append(ref.encode_temperature(
            TemperatureSample(t, float(run.temperature_c[i])), saturate=True))
        expected.append(ref.encode_rate(
            RateSample(t, float(x[i]), 0.0, float(-x[i])), saturate=True))
    assert [bytes(m.data) for m in frames] == [bytes(m.data) for m in expected]
    nxt = enc.encode_rate(RateSample(9.0, 0, 0, 0))
    assert FrameDecoder().decode(nxt).counter == (5 + n) % 16  # type: ignore[union-attr]


CUSTOM_DBC, CUSTOM_MAP = USER_DBC, USER_SIGNAL_MAP


def test_big_endian_extended_dbc_and_float_fallback(tmp_path: Path) -> None:
    dbc = tmp_path / "imu.dbc"
    dbc.write_text(CUSTOM_DBC)
    run = Run(name="imu", time_s=np.array([0.0, 1.0, 2.0]), temperature_c=np.array([36.5, 1, 2]),
              rates_dps={"x": np.array([1.0, -3, 200]), "y": np.array([-0.5, 0, 0]),
                         "z": np.array([3.0, 2, -400])})
    frames = list(frames_from_run(run, encoder=FrameEncoder(dbc, CUSTOM_MAP)))
    ref = FrameEncoder(dbc, CUSTOM_MAP)
    rates = [m for m in frames if m.is_extended_id]
    # Motorola, by hand (see tests/codecs/test_can.py): 1.0, -0.5, 3.0 -> 01 4F F6 00 64 00
    assert bytes(rates[0].data) == bytes.fromhex("014FF6006400")
    assert rates[0].arbitration_id == 0x18FF1001
    for i, m in enumerate(rates):
        want = ref.encode_rate(RateSample(float(i), *(float(run.rates_dps[a][i]) for a in "xyz")),
                               saturate=True)
        assert bytes(m.data) == bytes(want.data)
    temps = [m for m in frames if not m.is_extended_id]
    assert [FrameDecoder(dbc, CUSTOM_MAP).decode(m).temperature_c for m in temps] == [  # type: ignore[union-attr]
        36.5, 1.0, 2.0]


# ------------------------------------------------------------------------- the player


def test_real_time_schedule_is_absolute() -> None:
    frames = [msg_at(t) for t in (100.0, 100.5, 100.5, 101.0, 103.0)]
    fake = FakeTime(50.0, oversleep_s=0.01)  # every wait overshoots by 10 ms
    sent_at: list[float] = []
    sink = ListSink(on_send=lambda m: sent_at.append(fake.now))
    stats = play(frames, sink, speed=2.0, clock=fake.clock, stop=fake)
    # due = 50 + (t - 100) / 2 -> 50, 50.25, 50.25, 50.5, 51.5; sends happen after each overshoot
    assert sent_at == pytest.approx([50.0, 50.26, 50.26, 50.51, 51.51])
    # the schedule does not drift: each wait is measured from the absolute due time
    assert fake.waits == pytest.approx([0.25, 0.24, 0.99])
    assert (stats.frames_sent, stats.rate_frames, stats.stopped) == (5, 5, False)
    assert stats.sensor_span_s == 3.0 and stats.duration_s == pytest.approx(1.51)
    assert [m.timestamp for m in sink.frames] == [100.0, 100.5, 100.5, 101.0, 103.0]


def test_behind_schedule_sends_without_waiting() -> None:
    fake = FakeTime(0.0)

    def slow_sink(msg: can.Message) -> None:
        fake.now += 2.0  # each send takes 2 s of clock time, longer than the frame spacing

    stats = play([msg_at(0.1 * i) for i in range(10)], ListSink(on_send=slow_sink), speed=1.0,
                 clock=fake.clock, stop=fake)
    assert fake.waits == [] and stats.frames_sent == 10


@pytest.mark.parametrize("speed", [0.0, float("inf")])
def test_as_fast_as_possible_never_waits(short_run: Run, speed: float) -> None:
    fake = FakeTime(0.0)
    sink = ListSink()
    stats = play(frames_from_run(short_run, encoder=FrameEncoder()), sink, speed=speed,
                 clock=fake.clock, stop=fake)
    n = len(short_run)
    assert fake.waits == []
    assert (stats.frames_sent, stats.rate_frames, stats.temperature_frames) == (2 * n, n, n)
    assert stats.sensor_span_s == pytest.approx(short_run.duration_s)
    assert sink.frames[-1].timestamp == short_run.time_s[-1]  # sensor time, not wall clock


def test_stop_interrupts_a_wait_and_pending_frames_are_not_counted() -> None:
    fake = FakeTime(0.0)
    fake.stop_on_wait = True  # the stop arrives while the player waits for frame 2
    stats = play([msg_at(0.0), msg_at(0.0), msg_at(5.0)], ListSink(), clock=fake.clock, stop=fake)
    assert (stats.frames_sent, stats.stopped) == (2, True) and fake.waits == [5.0]
    already = FakeTime(0.0)
    already.flag = True
    assert play([msg_at(0.0)], ListSink(), stop=already).frames_sent == 0
    # a saturated frame pulled but not sent is not counted
    run = make_run([0.0, 1.0], [20.0, 20.0], [0.0, 500.0])  # frames T0 R0 T1 R1(saturated)
    stop = threading.Event()
    sink = ListSink(on_send=lambda m: len(sink.frames) == 3 and stop.set())
    stats = play(frames_from_run(run, encoder=FrameEncoder(), temperature_period_s=0.0), sink,
                 speed=0, stop=stop)
    assert (stats.frames_sent, stats.saturated, stats.stopped) == (3, 0, True)


def test_real_event_interrupts_real_time_playback() -> None:
    stop, first_sent = threading.Event(), threading.Event()
    stopper = threading.Thread(target=lambda: first_sent.wait(TIMEOUT_S) and stop.set())
    stopper.start()
    # the second frame is due in 1000 s: only the stop event can end this call
    stats = play([msg_at(0.0), msg_at(1000.0)], ListSink(on_send=lambda m: first_sent.set()),
                 speed=1.0, stop=stop)
    stopper.join(TIMEOUT_S)
    assert (stats.frames_sent, stats.stopped) == (1, True)


def test_max_frames_progress_and_bad_speed() -> None:
    fake = FakeTime(0.0)
    calls: list[int] = []
    frames = [msg_at(float(i), TEMP_ID if i % 2 else RATE_ID) for i in range(11)]
    stats = play(frames, ListSink(), clock=fake.clock, stop=fake, progress=calls.append,
                 progress_interval_s=1.0)
    # frame k is due at k s; before waiting for it the clock reads k - 1 >= the next report
    assert calls == list(range(2, 11))
    assert (stats.rate_frames, stats.temperature_frames) == (6, 5)
    assert play(frames, ListSink(), speed=0, max_frames=4).frames_sent == 4
    for bad in (-1.0, float("nan")):
        with pytest.raises(ConfigError, match="speed"):
            play(frames, ListSink(), speed=bad)


def test_candump_write_and_replay_round_trip(short_run: Run, tmp_path: Path) -> None:
    log = tmp_path / "run.log"
    original = list(frames_from_run(short_run, encoder=FrameEncoder(), t0_s=1_700_000_000.0))
    with CandumpSink(log, channel="vcan0") as sink:
        first = play(original, sink, speed=0)
    assert log.read_text().splitlines()[0].startswith("(1700000000.000000) vcan0 121#")
    replay = frames_from_candump(log)
    sink2 = ListSink()
    second = play(replay, sink2, speed=0)
    assert (second.frames_sent, second.rate_frames, second.temperature_frames) == (
        first.frames_sent, first.rate_frames, first.temperature_frames)
    assert [(m.arbitration_id, bytes(m.data), round(m.timestamp * 1e6)) for m in sink2.frames] == [
        (m.arbitration_id, bytes(m.data), round(m.timestamp * 1e6)) for m in original]
    assert all(m.channel is None for m in sink2.frames)


# ---------------------------------------------------------------------------- the CLI


def test_parser_accepts_the_deploy_units() -> None:
    parser = argparse.ArgumentParser(prog="gyrotherm")
    sim = parser.add_subparsers(dest="command").add_parser("sim")
    register(sim.add_subparsers(dest="sim_command"))
    for unit in ("gyrotherm-sim.service", "gyrotherm-sim-socketcand.service"):
        text = (ROOT / "deploy" / "systemd" / unit).read_text()
        exec_start = re.search(r"^ExecStart=(.*)$", text, re.MULTILINE)
        assert exec_start is not None
        args = parser.parse_args(exec_start.group(1).split()[1:])
        assert args.func.__name__ == "cmd_stream" and args.channel == "vcan0"
    assert (args.interface, args.host, args.port, args.chamber) == (
        "socketcand", "127.0.0.1", 29536, None)


def test_cli_socketcan_unavailable_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    code = stream_main(["--chamber", "5", "--rate-hz", "1", "--hold-s", "10",
                        "--interface", "socketcan", "--channel", "gtnodev0"])
    err = capsys.readouterr().err
    assert code == 2
    assert "gyrotherm: error: interface 'socketcan', channel 'gtnodev0'" in err


def test_cli_option_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert stream_main(["--interface", "socketcan", "--port", "1"]) == 2
    assert "--port: only --interface socketcand-server" in capsys.readouterr().err
    assert stream_main(["--interface", "none"]) == 2
    assert "--write-candump" in capsys.readouterr().err
    assert stream_main(["--run", str(tmp_path / "missing.csv"), "--interface", "none",
                        "--write-candump", str(tmp_path / "x.log")]) == 2
    assert "missing.csv" in capsys.readouterr().err
    assert stream_main(["--candump", str(tmp_path / "missing.log"), "--port", "0"]) == 2
    assert "missing.log: cannot open candump log" in capsys.readouterr().err
    no_client = ["--chamber", "5", "--rate-hz", "1", "--hold-s", "10", "--port", "0"]
    assert stream_main([*no_client, "--wait-timeout-s", "0.1"]) == 3
    out, err = capsys.readouterr()
    assert out.startswith("listening on 127.0.0.1:") and "fewer than 1 socketcand clients" in err


def test_cli_writes_candump_and_replays_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second = tmp_path / "a.log", tmp_path / "b.log"
    common = ["--interface", "none", "--speed", "0", "-q"]
    assert stream_main(["--chamber", "5", "--rate-hz", "2", "--hold-s", "60", *common,
                        "--write-candump", str(first), "--max-frames", "100"]) == 0
    out = capsys.readouterr().out
    assert "summary: frames_sent=100 rate_frames=50 temperature_frames=50" in out
    assert stream_main(["--candump", str(first), *common, "--write-candump", str(second)]) == 0
    assert "frames_sent=100" in capsys.readouterr().out
    assert second.read_text() == first.read_text() and len(first.read_text().splitlines()) == 100


def _lines(stream: object) -> queue.Queue[str]:
    q: queue.Queue[str] = queue.Queue()

    def pump() -> None:
        for line in stream:  # type: ignore[attr-defined]
            q.put(line)
        q.put("")

    threading.Thread(target=pump, daemon=True).start()
    return q


@pytest.fixture
def stream_cli() -> Iterator[list[subprocess.Popen[str]]]:
    procs: list[subprocess.Popen[str]] = []
    yield procs
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait(TIMEOUT_S)
        for f in (p.stdout, p.stderr):
            if f is not None:
                f.close()


def start_cli(procs: list[subprocess.Popen[str]], *args: str) -> tuple[int, queue.Queue[str]]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([*CLI, "--port", "0", "--wait-timeout-s", str(TIMEOUT_S), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    procs.append(proc)
    lines = _lines(proc.stdout)
    first = lines.get(timeout=TIMEOUT_S)
    m = re.fullmatch(r"listening on 127\.0\.0\.1:(\d+) channel vcan0\n", first)
    assert m, first
    return int(m.group(1)), lines


def summary(lines: queue.Queue[str]) -> dict[str, str]:
    line = lines.get(timeout=TIMEOUT_S)
    assert line.startswith("summary: "), line
    return dict(kv.split("=", 1) for kv in line.split()[1:])


def test_cli_serves_a_run_to_a_socketcand_client(
    stream_cli: list[subprocess.Popen[str]]
) -> None:
    port, lines = start_cli(stream_cli, "--chamber", "5", "--rate-hz", "2", "--hold-s", "60",
                            "--speed", "0")
    run = chamber_runs([5], seed=0, rate_hz=2.0, hold_s=60.0)[0]
    expected = list(frames_from_run(run, encoder=FrameEncoder()))
    assert len(expected) == 2 * 841  # 420 s at 2 Hz
    bus = can.Bus(interface="socketcand", host="127.0.0.1", port=port, channel="vcan0",
                  ignore_config=True)
    got: list[can.Message] = []
    try:
        while len(got) < len(expected):
            msg = bus.recv(timeout=TIMEOUT_S)
            assert msg is not None, f"only {len(got)} of {len(expected)} frames"
            got.append(msg)
    finally:
        bus.shutdown()
    assert [(m.arbitration_id, bytes(m.data), round(m.timestamp * 1e6)) for m in got] == [
        (m.arbitration_id, bytes(m.data), round(m.timestamp * 1e6)) for m in expected]
    decoder = FrameDecoder(on_counter_jump="reject")
    assert all(not hasattr(decoder.decode(m), "reason") for m in got)
    fields = summary(lines)
    assert fields["frames_sent"] == "1682" and fields["rate_frames"] == "841"
    assert fields["temperature_frames"] == "841" and fields["dropped"] == "0"
    assert fields["sensor_span_s"] == "420.000" and fields["stopped"] == "no"
    assert stream_cli[0].wait(TIMEOUT_S) == 0


def test_cli_stops_cleanly_on_sigterm(stream_cli: list[subprocess.Popen[str]]) -> None:
    port, lines = start_cli(stream_cli, "--chamber", "5", "--speed", "1")  # 2 h in real time
    bus = can.Bus(interface="socketcand", host="127.0.0.1", port=port, channel="vcan0",
                  ignore_config=True)
    try:
        first = bus.recv(timeout=TIMEOUT_S)
        assert first is not None and first.timestamp == 0.0
        stream_cli[0].send_signal(signal.SIGTERM)
        fields = summary(lines)
    finally:
        bus.shutdown()
    assert fields["stopped"] == "yes" and fields["signal"] == "SIGTERM"
    assert int(fields["frames_sent"]) >= 1
    assert stream_cli[0].wait(TIMEOUT_S) == 0
