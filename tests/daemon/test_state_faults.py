"""What the daemon reads from disk cannot poison the vehicle (issue "vehicle state").

* Unsafe paths (FIFO, device, directory, huge file, socket) are refused without being
  opened or read, for the state file and the calibration file, without blocking.
* Hostile JSON (400-digit integers, nesting 100 000 deep, 1e999) is one CalibrationError
  naming the file and the field.
* A saved state out of bounds (zero beyond max_offset_dps, T_s 1e308, hysteresis
  extremes 1e308, a power-on in the future or 1e13 s back) drops that part with a
  warning naming the field, the rates stay sane, and the bad value is not saved again.
* Fuzz (hypothesis, derandomised): random bytes, random JSON and a real saved state with
  one leaf replaced by a random value never raise out of the restore, and every rate
  published afterwards has a finite bias within the plausibility bound and a zero within
  max_offset_dps.
"""

from __future__ import annotations

import copy
import json
import math
import os
import socket
import tempfile
import threading
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gyrotherm import CalibrationError
from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run
from gyrotherm.codecs._wire_decode import decode_rate
from gyrotherm.compensation import Calibration, ZeroConfig, read_calibration
from gyrotherm.compensation._plausibility import MAX_BIAS_DPS
from gyrotherm.daemon import Pipeline
from gyrotherm.daemon._effects_store import EffectsKeeper, SavedEffects, load, save
from streamkit import RecordingSink, make_v2, run_frames

ZERO = ZeroConfig(window_s=30.0, settle_s=20.0, max_offset_dps=1.0)
BLOCK_BOUND_S = 5.0  # a read that blocks is a hang; the real ones take microseconds


def _unsafe(kind: str, path: Path) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev_zero_link":
        path.symlink_to("/dev/zero")
    elif kind == "directory":
        path.mkdir()
    elif kind == "huge":
        with open(path, "wb") as f:
            f.truncate(64 << 20)  # sparse: 64 MiB of zeros
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.bind(str(path))
        s.close()


WHY = {"fifo": "is a FIFO", "dev_zero_link": "is a character device",
       "directory": "is a directory", "huge": "bytes, more than", "socket": "is a socket"}


def _in_thread(fn: Any) -> BaseException | None:
    """Run ``fn`` on a thread; the exception it raised (it must not block)."""
    out: list[BaseException | None] = [None]

    def target() -> None:
        try:
            fn()
        except BaseException as exc:
            out[0] = exc

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(BLOCK_BOUND_S)
    assert not th.is_alive(), "the read blocked"
    return out[0]


@pytest.mark.parametrize("kind", list(WHY))
def test_unsafe_paths_are_refused_unopened(tmp_path: Path, kind: str) -> None:
    state, cal = tmp_path / "v.s.effects-state.json", tmp_path / "cal.json"
    _unsafe(kind, state)
    _unsafe(kind, cal)
    for path, reader in ((state, load), (cal, read_calibration)):
        exc = _in_thread(lambda p=path, r=reader: r(p))
        assert isinstance(exc, CalibrationError), exc
        assert str(exc).startswith(f"{path}: ") and WHY[kind] in str(exc)


@pytest.mark.parametrize(("text", "why"), [
    ('{"schema": "gyrotherm.effects-state", "version": 1, "power_on_s": 1' + "0" * 400 + "}",
     "field 'power_on_s': an integer of 401 digits"),
    ("[" * 100_000 + "]" * 100_000, "JSON nested 100000 deep"),
    ('{"schema": "gyrotherm.effects-state", "version": 1, "time_s": 1e999}',
     "field 'time_s': the number 1e999 overflows a double"),
    ('{"schema": "gyrotherm.effects-state", "version": 1, "time_s": NaN}',
     "field 'time_s': NaN is not a finite number"),
    ("\xff\xfe", "not UTF-8"),
])
def test_hostile_json_is_one_error_naming_the_field(tmp_path: Path, text: str,
                                                    why: str) -> None:
    path = tmp_path / "state.json"
    path.write_bytes(text.encode("latin-1") if text.startswith("\xff") else text.encode())
    with pytest.raises(CalibrationError, match=f"^{path}: .*{why}"):
        load(path)


# --- a real saved state, then edited ------------------------------------------------


@pytest.fixture(scope="module")
def v2(stream_calibration: Calibration) -> Calibration:
    return make_v2(stream_calibration)


@pytest.fixture(scope="module")
def saved_run(short_runs: list[Run], v2: Calibration) -> tuple[Run, dict[str, Any]]:
    """A run of 400 rows; the state document a daemon saved after its first 300."""
    run = short_runs[0].slice(0, 400)
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=v2, zero=ZERO)  # type: ignore[arg-type]
    frames = list(run_frames(run, FrameEncoder()))
    for msg in frames[:600]:
        pipe.process(msg, 1.0e9)
    snap = pipe.compensation.snapshot()
    assert snap is not None and snap.zero is not None and snap.zero["status"] == "done"
    doc = {"schema": "gyrotherm.effects-state", "version": 1, "vehicle": "car",
           "sensor": "imu0", "calibration_id": "cid", "power_on_s": snap.power_on_s,
           "time_s": snap.time_s, "compensator": snap.state, "zero": snap.zero}
    return run, doc


def _restart(tmp_path: Path, doc: Any, run: Run, v2: Calibration, *,
             raw: bytes | None = None) -> tuple[Pipeline, RecordingSink, EffectsKeeper]:
    """A new pipeline restored from ``doc`` (or ``raw`` bytes), fed rows 300… ."""
    state_dir = tmp_path / "state"
    state_dir.mkdir(exist_ok=True)
    keeper = EffectsKeeper(state_dir, "car", "imu0")
    assert keeper.path is not None
    keeper.path.write_bytes(raw if raw is not None else json.dumps(doc).encode())
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=v2, zero=ZERO)  # type: ignore[arg-type]
    keeper.restore(pipe.compensation, "cid")
    for msg in list(run_frames(run, FrameEncoder()))[600:]:
        pipe.process(msg, 1.0e9)
    return pipe, sink, keeper


def _assert_sane(pipe: Pipeline, sink: RecordingSink) -> None:
    """Every rate: a finite bias within the plausibility bound plus max_offset_dps; the
    zero within max_offset_dps; every frame published or dropped (none here)."""
    assert pipe.counters().drops == {}
    for p in sink.rates:
        m = decode_rate(p)
        assert all(math.isfinite(b) and abs(b) <= MAX_BIAS_DPS + ZERO.max_offset_dps
                   for b in m.bias_dps), m
    zero = pipe.compensation.zero
    assert zero is not None and all(abs(v) <= ZERO.max_offset_dps for v in zero.offset_dps)


def test_the_saved_state_as_written_is_restored(
        tmp_path: Path, saved_run: tuple[Run, dict[str, Any]], v2: Calibration) -> None:
    run, doc = saved_run
    pipe, sink, _ = _restart(tmp_path, doc, run, v2)
    assert pipe.compensation.power_on_s == doc["power_on_s"]
    zero = pipe.compensation.zero
    assert zero is not None and list(zero.offset_dps) == doc["zero"]["offset_dps"]
    _assert_sane(pipe, sink)


def _edit(doc: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    out = copy.deepcopy(doc)
    node = out
    keys = path.split(".")
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    last = keys[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value
    return out


@pytest.mark.parametrize(("path", "value", "warning", "kept"), [
    ("zero.offset_dps", [50.0, -50.0, 5.0], "offset_dps[0] = 50.0 °/s is beyond "
     "max_offset_dps = 1 °/s", "effects"),
    ("zero.offset_dps", [1e308, 0.0, 0.0], "offset_dps[0] = 1e+308 °/s is beyond", "effects"),
    ("zero.done_s", 1e12, "done_s = 1000000000000.0 s is outside the saved run", "effects"),
    ("compensator.axes.x.structure_temperature_c", 1e308,
     "axes.x.structure_temperature_c' = 1e+308 °C is outside the sensor's range", "zero"),
    ("compensator.axes.x.hysteresis_high_c", 1e308,
     "axes.x.hysteresis_high_c' = 1e+308 °C is outside the sensor's range", "zero"),
    ("compensator.axes.x.power_on_s", -1e13, "axes.x.power_on_s' = -10000000000000.0 s disagrees",
     "zero"),
    ("power_on_s", -1e13, "beyond ±1e12 s", "nothing"),
    ("power_on_s", 1e9, "a power-on in the future", "nothing"),
])
def test_a_saved_state_out_of_bounds_drops_that_part(
        tmp_path: Path, saved_run: tuple[Run, dict[str, Any]], v2: Calibration,
        caplog: pytest.LogCaptureFixture, path: str, value: Any, warning: str,
        kept: str) -> None:
    run, doc = saved_run
    pipe, sink, keeper = _restart(tmp_path, _edit(doc, path, value), run, v2)
    assert warning in caplog.text
    comp = pipe.compensation
    zero = comp.zero
    assert zero is not None
    if kept == "effects":  # the effects continue, the zero is measured again (untrusted)
        assert comp.power_on_s == doc["power_on_s"] and not zero.trusted
    elif kept == "zero":  # the zero and the power-on survive, the effects start afresh
        assert comp.power_on_s == doc["power_on_s"]
        assert list(zero.offset_dps) == doc["zero"]["offset_dps"]
    else:  # nothing: a power-on at the first frame; whether the gyro kept running is
        # unknown, so the zero measured again is untrusted
        assert comp.power_on_s == run.time_s[300] and not zero.trusted
    _assert_sane(pipe, sink)
    # the bad value is never saved again
    keeper.save(comp, "cid", 0.0, force=True)
    assert keeper.path is not None
    again = json.loads(keeper.path.read_text())
    node: Any = again
    for k in path.split("."):
        node = node[k]
    assert node != value
    assert again["power_on_s"] <= again["time_s"]
    assert all(abs(v) <= ZERO.max_offset_dps for v in again["zero"]["offset_dps"])


# --- fuzz ---------------------------------------------------------------------------

_FIELDS = ["power_on_s", "time_s", "calibration_id", "zero.status", "zero.offset_dps.0",
           "zero.done_s", "zero.start_s", "zero.trusted", "zero.unverified",
           *(f"compensator.axes.{a}.{f}" for a in "xyz"
             for f in ("samples", "time_s", "power_on_s", "structure_temperature_c",
                       "hysteresis_direction", "hysteresis_high_c", "hysteresis_low_c",
                       "hysteresis_travel_c", "hysteresis_h_start", "hysteresis_h"))]
_VALUES = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False), st.integers(-(10**30), 10**30),
    st.sampled_from([1e308, -1e308, 0.0, -0.0, 5e-324, 1e13, -1e13]),
    st.text(max_size=5), st.none(), st.booleans(), st.lists(st.integers(), max_size=4))
_JSON = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=False, allow_infinity=False)
    | st.integers() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner,
                                                                 max_size=4),
    max_leaves=20)


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(_FIELDS), value=_VALUES)
def test_fuzz_one_field_of_a_real_state(
        tmp_path: Path, saved_run: tuple[Run, dict[str, Any]], v2: Calibration,
        field: str, value: Any) -> None:
    run, doc = saved_run
    try:
        edited = _edit(doc, field, value)
        raw = json.dumps(edited).encode()
    except (OverflowError, ValueError):
        return
    sub = Path(tempfile.mkdtemp(dir=tmp_path))
    pipe, sink, _ = _restart(sub, None, run, v2, raw=raw)
    _assert_sane(pipe, sink)


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.one_of(st.binary(max_size=300), _JSON.map(lambda j: json.dumps(j).encode())))
def test_fuzz_random_bytes_and_json(
        tmp_path: Path, saved_run: tuple[Run, dict[str, Any]], v2: Calibration,
        data: bytes) -> None:
    run, _ = saved_run
    sub = Path(tempfile.mkdtemp(dir=tmp_path))
    pipe, sink, _ = _restart(sub, None, run, v2, raw=data)
    _assert_sane(pipe, sink)


def test_save_then_load_round_trips(tmp_path: Path,
                                    saved_run: tuple[Run, dict[str, Any]]) -> None:
    from gyrotherm.daemon._compensation import EffectsSnapshot

    _, doc = saved_run
    path = tmp_path / "s.json"
    snap = EffectsSnapshot(doc["power_on_s"], doc["time_s"], doc["compensator"], doc["zero"])
    save(path, SavedEffects("car", "imu0", "cid", snap))
    back = load(path)
    assert back is not None
    assert back.snapshot.state == doc["compensator"] and back.snapshot.zero == doc["zero"]


_STRINGISH = st.text(alphabet='[]{}"\\ab:,', max_size=12)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(doc=st.recursive(st.none() | st.integers() | _STRINGISH,
                        lambda inner: st.lists(inner, max_size=3)
                        | st.dictionaries(_STRINGISH, inner, max_size=3), max_leaves=15))
def test_nesting_depth_counts_only_structure(doc: Any) -> None:
    """The bracket count the parser relies on (before ``json`` recurses) equals the
    document's real depth, whatever quotes, backslashes and brackets its strings hold
    (a regular expression for strings once backtracked quadratically on them)."""
    from gyrotherm._safefile import nesting_depth

    def depth(o: Any) -> int:
        if isinstance(o, dict):
            return 1 + max([depth(v) for v in o.values()], default=0)
        if isinstance(o, list):
            return 1 + max([depth(v) for v in o], default=0)
        return 0

    assert nesting_depth(json.dumps(doc)) == depth(doc)


@pytest.mark.parametrize("status", ["done", "failed"])
def test_a_state_of_another_calibration_that_the_gyro_continues(
        tmp_path: Path, saved_run: tuple[Run, dict[str, Any]], v2: Calibration,
        status: str) -> None:
    """The saved state is of another calibration (not taken back) but the first frame
    continues its time: the gyro kept running and may be moving, so the zero is measured
    again untrusted (ZERO_UNVERIFIED when taken), and one that had failed stays failed."""
    run, doc = saved_run
    other = _edit(doc, "calibration_id", "another-calibration")
    other = _edit(other, "zero.status", status)
    pipe, sink, _ = _restart(tmp_path, other, run, v2)
    zero = pipe.compensation.zero
    assert zero is not None and not zero.trusted
    if status == "failed":
        assert zero.status.name == "FAILED"
    else:
        assert zero.status.name == "DONE" and zero.unverified
    _assert_sane(pipe, sink)
