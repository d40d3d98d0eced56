"""Per-log work on workers (gyrotherm.cli._pool, _prep): serial, --jobs 2 and a Dask
LocalCluster of 2 worker processes give byte-identical outputs in the same order; a
failed log is one error line, the others go on, exit 2; Dask is imported only with
--dask-scheduler and its absence names the extra."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from biglogkit import write_dataflash, write_ulog
from fleetkit import write_fleet
from gyrotherm.cli import main
from gyrotherm.cli._pool import Workers, map_logs
from gyrotherm.cli._prep import Prep, prepare_log
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.readers import InputSpec

FIT_TIME = re.compile(rb'"fit_time_utc": "[^"]*"')
ELAPSED = re.compile(rb'"elapsed_s": [0-9.e+-]+')


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Mixed formats: two IMUs' chamber run files, a PX4 ULog and an ArduPilot .bin."""
    d = tmp_path_factory.mktemp("workers")
    runs = write_fleet(d, heating_min=[10, 30], seed=3, hold_s=600.0,
                       imus=(("veh-a", "imu0", "11"), ("veh-a", "imu1", "12")))
    write_ulog(d / "px4.ulg", 6000, seed=2)
    write_dataflash(d / "ardu.bin", 6000, seed=4)
    return [*runs, d / "px4.ulg", d / "ardu.bin"]


@pytest.fixture(scope="module")
def dask_address() -> Iterator[str]:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        yield str(cluster.scheduler_address)


def _dies_on(path: str) -> str:
    """A per-log function whose worker dies on a log named ``die*``."""
    if Path(path).name.startswith("die"):
        os._exit(3)
    return path.upper()


def _lost(path: str, why: str) -> str:
    return f"LOST {path}: {why}"


def _outputs(directory: Path) -> dict[str, bytes]:
    """Every file written under ``directory``, the fit time and elapsed time blanked
    (they say when the command ran, not what it computed), and the directory's own
    name in the paths the JSON documents give."""
    def clean(data: bytes) -> bytes:
        return ELAPSED.sub(b"", FIT_TIME.sub(b"", data)).replace(str(directory).encode(),
                                                                 b"OUT")

    return {str(p.relative_to(directory)): clean(p.read_bytes())
            for p in sorted(directory.rglob("*")) if p.is_file()}


def _run_all(logs: list[Path], out: Path, workers: list[str]) -> dict[str, bytes]:
    files = [str(p) for p in logs]
    imu0 = [str(p) for p in logs if "imu0" in p.name]
    commands = {
        "fit": ["fit", *files, "--out", str(out / "fit"), "--no-validation", "--force",
                "--json", str(out / "fit.json")],
        "import": ["import", *files, "--out", str(out / "import"),
                   "--json", str(out / "import.json")],
        "diagnose": ["diagnose", *imu0, "--no-simulation", "--json", str(out / "diag.json")],
        "fleet": ["fleet", *files[:-2], "--out", str(out / "fleet"),
                  "--json", str(out / "fleet.json")],
    }
    for name, argv in commands.items():
        assert main(["-q", *argv, *workers]) == 0, name
    return _outputs(out)


def test_serial_processes_and_dask_give_identical_outputs(
        logs: list[Path], dask_address: str, tmp_path: Path) -> None:
    serial = _run_all(logs, tmp_path / "serial", ["--jobs", "1"])
    pooled = _run_all(logs, tmp_path / "jobs2", ["--jobs", "2"])
    dasked = _run_all(logs, tmp_path / "dask", ["--dask-scheduler", dask_address])
    assert len(serial) >= 12  # 3 JSON documents, calibrations, imported run files
    assert list(pooled) == list(serial) and list(dasked) == list(serial)
    for name, data in serial.items():
        assert pooled[name] == data, name
        assert dasked[name] == data, name
    order = [w["run"] for w in json.loads(serial["import.json"])["written"]]
    assert order[:4] == [p.stem for p in logs[:4]]  # the inputs' order, not finishing order


def test_a_failed_log_is_named_and_the_others_go_on(
        logs: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "broken.ulg"
    bad.write_bytes(b"ULog\x01\x12\x35" + b"\x00" * 40)
    files = [str(logs[0]), str(bad), str(logs[1])]
    for workers in (["--jobs", "1"], ["--jobs", "2"]):
        out = tmp_path / workers[1]
        capsys.readouterr()
        assert main(["-q", "import", *files, "--out", str(out), *workers]) == 2
        err = capsys.readouterr().err
        assert re.search(rf"^gyrotherm: error: {re.escape(str(bad))}: ", err, re.M), err
        assert err.count("gyrotherm: error:") == 1
        assert sorted(p.name for p in out.iterdir()) == sorted(
            f"{Path(f).stem}.csv" for f in files if f != str(bad))
        cal = tmp_path / f"cal-{workers[1]}.json"
        assert main(["-q", "fit", str(logs[0]), str(bad), "--out", str(cal), "--force",
                     "--no-validation", *workers]) == 2
        assert cal.is_file()
    capsys.readouterr()
    assert main(["-q", "import", str(bad), str(bad), "--out", str(tmp_path / "none"),
                 "--jobs", "2"]) == 2  # all failed: each named, nothing written
    assert capsys.readouterr().err.count(f"gyrotherm: error: {bad}") == 2
    assert not (tmp_path / "none").exists()


def test_workers_return_headers_and_features_not_whole_runs(logs: list[Path]) -> None:
    prep = Prep(spec=InputSpec(), estimator=EstimatorConfig(), keep_rows=False)
    result = prepare_log(str(logs[-2]), prep)
    assert not result.error and result.runs and result.features
    assert all(len(r) == 0 and r.metadata["device_id"] for r in result.runs)
    assert all(f is not None and len(f.time_s) > 1000 for f in result.features)


def test_jobs_must_be_positive(logs: list[Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["-q", "import", str(logs[0]), "--out", "x", "--jobs", "0"]) == 2
    assert "--jobs 0" in capsys.readouterr().err


def test_dask_is_imported_only_with_the_option_and_its_absence_names_the_extra(
        logs: list[Path], tmp_path: Path) -> None:
    code = ("import sys\nfrom gyrotherm.cli import main\n"
            f"assert main(['-q', 'fit', {str(logs[0])!r}, {str(logs[1])!r}, '--out', "
            f"{str(tmp_path / 'c.json')!r}, '--force', '--jobs', '2']) == 0\n"
            "assert not {'dask', 'distributed'} & set(sys.modules), 'dask imported'\n"
            "sys.modules['distributed'] = None  # as if not installed\n"
            f"rc = main(['import', {str(logs[0])!r}, '--out', {str(tmp_path / 'i')!r}, "
            "'--dask-scheduler', 'tcp://127.0.0.1:8786'])\n"
            "assert rc == 2, rc\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert "pip install 'gyrotherm[fleet]'" in done.stderr


@pytest.mark.parametrize("where", ["jobs2", "dask"])
def test_a_dying_worker_loses_only_its_log(where: str, request: pytest.FixtureRequest) -> None:
    """Out of memory or killed: that log is lost (named), the others come back in order."""
    fn = _dies_on
    if where == "dask":
        def fn(path: str) -> str:  # local: pickled by value (workers cannot import tests)
            if Path(path).name.startswith("die"):
                os._exit(3)
            return path.upper()

        workers = Workers(scheduler=request.getfixturevalue("dask_address"))
    else:
        workers = Workers(jobs=2)
    paths = ["/a/x1", "/a/die", "/a/x2", "/a/x3", "/a/x4"]
    out = map_logs(fn, paths, workers, lost=_lost)
    assert [o for o in out if not o.startswith("LOST")] == ["/A/X1", "/A/X2", "/A/X3", "/A/X4"]
    assert out[1].startswith("LOST /a/die: ")
    if where == "dask":  # the nanny restarts the dead worker: let it finish before the
        # cluster closes (closing mid-restart is distributed's "can only join a started
        # process" at teardown, seen once under load)
        import distributed

        with distributed.Client(request.getfixturevalue("dask_address"), timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
