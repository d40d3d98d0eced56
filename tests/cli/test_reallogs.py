"""Every command on every real log: exit 0 with a usable result, or exit 2 with one line.

The corpus: the real third-party logs of ``reallogs/`` (PX4 ULogs from pyulog, an
ArduPlane DataFlash log, rosbag2 sqlite3 and MCAP bags; its SOURCE.md names each file's
repository, commit and licence), found as ``$GYROTHERM_REALLOGS``, else
``../shared/data/reallogs`` beside the project; plus the logs committed in
``tests/data`` (a real PX4 log's IMU topics, a real ROS 2 MCAP bag, and the project's
DataFlash/rosbag2/MCAP fixtures), which are always there. Each file is also tried cut at
60 %, cut to its first 100 bytes (inside the header), empty, and renamed (``.renamed``:
detection by content), copies made here.

On each, ``import``, ``fit`` (and ``fit --force``, past the quality gates), ``evaluate``,
``diagnose`` and ``export`` run in-process
(:func:`gyrotherm.cli.main`). Accepted: exit 0 with a usable result (run files that read
back to the log's own values as pyulog decodes them, calibrations that load, strict JSON
scores), or exit 2 whose stderr ends in exactly one ``gyrotherm: error:`` line naming the
file. Never an exception, a traceback, or a numpy warning.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import read_run
from gyrotherm.compensation import load_calibration
from gyrotherm.readers import InputSpec, read_runs

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
COMMANDS = ("import", "fit", "evaluate", "diagnose", "export")


def corpus_dir() -> Path | None:
    candidates = [os.environ.get("GYROTHERM_REALLOGS", ""),
                  str(ROOT.parent / "shared" / "data" / "reallogs"),
                  "/work/shared/data/reallogs"]
    return next((Path(c) for c in candidates if c and (Path(c) / "SOURCE.md").is_file()), None)


def corpus_files() -> list[Path]:
    """The real corpus (when present) and the committed logs of tests/data."""
    found: list[Path] = []
    real = corpus_dir()
    if real is not None:
        found += sorted(p for p in real.glob("*/*") if p.name != "SOURCE.md")
    found += [DATA / n for n in ("px4_sample_log_small_imu.ulg", "px4_two_gyros.ulg",
                                 "ardupilot_two_imus.bin", "rosbag2_imu", "imu.mcap",
                                 "ros2_talker.mcap")]
    return found


def _cases() -> list[tuple[Path, str]]:
    return [(p, v) for p in corpus_files()
            for v in (("original",) if p.is_dir() else
                      ("original", "cut60", "head100", "empty", "renamed"))]


def _variant(path: Path, kind: str, where: Path) -> Path:
    if kind == "original":
        return path
    data = path.read_bytes()
    out = where / (f"{path.stem}.renamed" if kind == "renamed" else f"{kind}-{path.name}")
    out.write_bytes({"cut60": data[: len(data) * 6 // 10], "head100": data[:100],
                     "empty": b"", "renamed": data}[kind])
    return out


def run_cli(argv: list[str]) -> tuple[int, str, list[str]]:
    """Exit code, stdout and stderr lines of one command; an exception or a warning
    (numpy's 'Mean of empty slice', …) fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["-q", *argv])
    return code, out.getvalue(), err.getvalue().splitlines()


def assert_clean_refusal(code: int, err: list[str], names: tuple[str, ...], argv: list[str]
                         ) -> None:
    assert code == 2, f"{argv}: exit {code}\n" + "\n".join(err)
    errors = [line for line in err if line.startswith("gyrotherm: error:")]
    assert len(errors) == 1 and err[-1] == errors[0], f"{argv}: {err}"
    assert not any("Traceback" in line for line in err), err
    assert any(n in errors[0] for n in names), f"{argv}: {errors[0]!r} names none of {names}"


@pytest.fixture(scope="module")
def reference_calibration(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A calibration from two simulated heating runs (for logs that fit none)."""
    where = tmp_path_factory.mktemp("ref")
    code, _, err = run_cli(["sim", "chamber", "--heating-min", "5", "10", "--out",
                            str(where / "sim"), "--seed", "1", "--rate-hz", "1"])
    assert code == 0, err
    code, _, err = run_cli(["fit", *map(str, sorted((where / "sim").glob("heat-*.csv"))),
                            "--out", str(where / "ref.json")])
    assert code == 0, err
    return where / "ref.json"


def _check_import(source: Path, out_dir: Path) -> None:
    """Each run file written reads back; for a ULog, to pyulog's own values exactly."""
    written = sorted(out_dir.glob("*.csv"))
    assert written, f"{source}: import exited 0 and wrote nothing"
    read = {r.name: r for r in read_runs(source, spec=InputSpec())}
    for f in written:
        run = read_run(f)
        assert run.metadata["source_sha256"]
        # bit for bit what the reader read
        direct = read[run.metadata["name"]] if "name" in run.metadata else read[run.name]
        np.testing.assert_array_equal(run.time_s, direct.time_s)
        np.testing.assert_array_equal(run.temperature_c, direct.temperature_c)
        for axis, values in direct.rates_dps.items():
            np.testing.assert_array_equal(run.rates_dps[axis], values)
        assert "*" not in f.name and "[" not in f.name and "?" not in f.name, f.name
        if not source.is_file() or source.read_bytes()[:7] != b"ULog\x01\x12\x35":
            continue
        from pyulog import ULog

        instance = int(run.metadata["instance"])
        gyro = next(d for d in ULog(str(source), ["sensor_gyro"]).data_list
                    if d.name == "sensor_gyro" and d.multi_id == instance)
        # the reader's documented rules (docs/inputs.md): rows with a non-finite value
        # dropped, sorted by time, a repeated time stamp keeps its first row
        stamp = gyro.data.get("timestamp_sample", gyro.data["timestamp"]).astype(np.int64)
        values = {k: gyro.data[k].astype(np.float64) for k in ("x", "y", "z", "temperature")}
        finite = np.all([np.isfinite(v) for v in values.values()], axis=0)
        order = np.argsort(stamp[finite], kind="stable")
        t_sorted = stamp[finite][order]
        first = np.concatenate([[True], np.diff(t_sorted) != 0])
        np.testing.assert_array_equal(run.time_s, t_sorted[first] * 1e-6)
        for axis in "xyz":
            want = np.degrees(values[axis][finite][order][first])
            np.testing.assert_allclose(run.rates_dps[axis], want, rtol=1e-8, atol=0,
                                       err_msg=f"{f.name} {axis}")


def _commands(f: Path, tmp: Path, cal: Path) -> Iterator[tuple[str, list[str], str]]:
    """Each command on ``f`` and the calibration file it uses ("" for none): ``fit``'s
    own first calibration when it wrote one, else ``cal``."""
    yield "import", ["import", str(f), "--out", str(tmp / "imported")], ""
    yield "fit", ["fit", str(f), "--out", str(tmp / "cal" / "{device}.json")], ""
    # the quality gates overridden: what they refused must still end in a clear error
    # (sample_px4_events.ulg, no row at rest: a numpy ValueError before)
    yield "fit --force", ["fit", str(f), "--force", "--out",
                          str(tmp / "forced" / "{device}.json")], ""
    fitted = sorted((tmp / "cal").glob("*.json"))
    use = str(fitted[0] if fitted else cal)
    yield "evaluate", ["evaluate", "--json", str(tmp / "scores.json"), use, str(f)], use
    yield "diagnose", ["diagnose", str(f), "--no-simulation"], ""
    yield "export", ["export", use, str(f), "--ardupilot", str(tmp / "tcal.param")], use


@pytest.mark.parametrize(("path", "kind"), _cases(),
                         ids=[f"{p.name}-{k}" for p, k in _cases()])
def test_every_command_exits_cleanly(path: Path, kind: str, tmp_path: Path,
                                     reference_calibration: Path) -> None:
    f = _variant(path, kind, tmp_path)
    for command, argv, cal in _commands(f, tmp_path, reference_calibration):
        code, _, err = run_cli(argv)
        if code != 0:
            assert_clean_refusal(code, err, (f.name, Path(cal).name) if cal else (f.name,),
                                 argv)
        elif command == "import":
            _check_import(f, tmp_path / "imported")
        elif command in ("fit", "fit --force"):
            for written in (tmp_path / ("cal" if command == "fit" else "forced")).glob("*.json"):
                assert load_calibration(written).provenance["quality"], written
        elif command == "evaluate":
            doc = json.loads((tmp_path / "scores.json").read_text(),
                             parse_constant=lambda c: pytest.fail(f"bare {c} in JSON"))
            assert doc["scores"], doc
        elif command == "export":
            assert (tmp_path / "tcal.param").stat().st_size > 0


def test_corpus_is_present_or_says_why() -> None:
    """The committed logs are always walked; the real corpus when it is beside the
    project (its files are other projects' data and live in shared/, not in git). Its
    files are those tests/data/REALLOGS.md lists, byte for byte (sha256)."""
    import hashlib
    import re

    listed = dict((name, digest) for digest, name in re.findall(
        r"^([0-9a-f]{64})  (\S+)$", (DATA / "REALLOGS.md").read_text(encoding="utf-8"),
        flags=re.M))
    assert len(listed) >= 10
    real = corpus_dir()
    if real is None:
        pytest.skip("real-log corpus not found: set GYROTHERM_REALLOGS or place it at "
                    "../shared/data/reallogs (tests/data/REALLOGS.md lists the files)")
    files = {p.relative_to(real).as_posix(): p for p in real.rglob("*")
             if p.is_file() and p.name != "SOURCE.md"}
    assert set(files) == set(listed)
    for name, path in files.items():
        assert hashlib.sha256(path.read_bytes()).hexdigest() == listed[name], name
        assert path.stat().st_size <= 5 * 1024 * 1024, path


def test_a_real_board_with_a_nan_temperature_gyro_keeps_the_other(tmp_path: Path) -> None:
    """The Pixhawk 5 log of the corpus: pyulog says sensor_gyro 1 logs NaN temperature
    throughout and 0 does not; import writes instance 0 and notes 1, not a refusal."""
    real = corpus_dir()
    if real is None or not (real / "px4" / "roboto_fmu_v5.ulg").is_file():
        pytest.skip("real-log corpus not found (see test_corpus_is_present_or_says_why)")
    from pyulog import ULog

    path = real / "px4" / "roboto_fmu_v5.ulg"
    nan = {d.multi_id: bool(np.isnan(d.data["temperature"]).all())
           for d in ULog(str(path), ["sensor_gyro"]).data_list}
    assert nan == {0: False, 1: True}
    code, _, err = run_cli(["import", str(path), "--out", str(tmp_path)])
    assert code == 0, err
    assert [f.name for f in tmp_path.glob("*.csv")] == ["roboto_fmu_v5-sensor_gyro0.csv"]
    assert err == [f"note: {path}: IMU instance(s) skipped, the others read: topic "
                   "'sensor_gyro' instance 1: no temperature in 10 sample(s)"]


def test_as_a_process_a_failure_is_one_line(tmp_path: Path) -> None:
    """The same through ``python -m gyrotherm`` (what a user runs): a ULog cut in its
    header, renamed ``.log``, refused in one line on stderr saying it is damaged (not
    the logger advice of a complete log without the topic), nothing on stdout (pyulog
    prints its findings there: they go into the message)."""
    import subprocess
    import sys

    head = tmp_path / "flight.log"
    head.write_bytes((DATA / "px4_two_gyros.ulg").read_bytes()[:40])
    proc = subprocess.run([sys.executable, "-m", "gyrotherm", "-q", "fit", str(head), "--out",
                           str(tmp_path / "c.json")], capture_output=True, text=True,
                          timeout=120, check=False, env={**os.environ, "GYROTHERM_DEBUG": ""})
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    (line,) = proc.stderr.splitlines()
    assert line.startswith(f"gyrotherm: error: {head}: a damaged or cut ULog (40 bytes; "
                           "pyulog: "), line
    assert line.endswith("give the complete file"), line
