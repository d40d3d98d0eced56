"""``gyrotherm fit`` and ``gyrotherm diagnose --calibration`` give the same paper
calibration from the same files (issue 19, item 4): the same estimator, chosen from the
readout; the same fit, one offset per run on 1-s blocks. Data: the independent
generator (``analysis.synth``), nothing injected, so the diagnosis writes the paper
model; its readout (0.125 °C refreshed every 1.28 s, a chamber column) is the truth the
chosen estimator is checked against."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.cli import main
from gyrotherm.codecs import write_run
from gyrotherm.compensation import load_calibration

CFG = SynthConfig(duration_s=3000.0, rate_hz=10.0)
SEED = 5


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    d = tmp_path_factory.mktemp("null")
    runs, _ = variant_runs(CFG, shapes={}, n_runs=4, seed=SEED)
    return [str(write_run(r, d / f"{r.name}.csv")) for r in runs]


@pytest.fixture(scope="module")
def both(files: list[str], tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, dict]:
    d = tmp_path_factory.mktemp("cals")
    a, b = d / "fit.json", d / "diagnose.json"
    assert main(["-q", "fit", *files, "--out", str(a), "--no-validation"]) == 0
    assert main(["-q", "diagnose", *files, "--calibration", str(b), "--no-simulation"]) == 0
    return json.loads(a.read_text()), json.loads(b.read_text())


def test_the_diagnosis_found_nothing_so_wrote_the_paper_model(both: tuple[dict, dict]) -> None:
    _, diag = both
    assert diag["version"] == 1 and "effects" not in diag
    assert diag["provenance"]["diagnosis"]["axes"]["x"]["effects"] == []


def test_same_estimator_scaling_range_and_coefficients(both: tuple[dict, dict]) -> None:
    fit, diag = both
    for key in ("model", "estimator", "scaling", "range"):
        assert fit[key] == diag[key], key
    np.testing.assert_allclose(fit["coefficients"]["x"], diag["coefficients"]["x"],
                               rtol=1e-9, atol=1e-12)
    assert fit["provenance"]["method"] == "offsets"


def test_the_estimator_is_the_generators_readout(both: tuple[dict, dict]) -> None:
    fit, _ = both
    est = fit["estimator"]
    assert est["update_period_s"] == pytest.approx(1.28, rel=0.10)  # the generator's refresh
    assert est["quantisation_c"] == pytest.approx(0.125, rel=1e-6)  # its LSB
    chosen = fit["provenance"]["estimator_chosen"]
    assert chosen["tau_from_chamber"] is True and chosen["runs"] == 4


def test_an_estimator_option_given_replaces_the_choice(files: list[str], tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    out = tmp_path / "given.json"
    assert main(["fit", *files, "--out", str(out), "--no-validation",
                 "--update-period-s", "1.0"]) == 0
    assert "note: estimator from the temperature readout" not in capsys.readouterr().err
    cal = load_calibration(out)
    assert cal.estimator.update_period_s == 1.0
    assert cal.estimator.tau_s == 120.0 and cal.estimator.quantisation_c == 0.01  # defaults
    assert cal.provenance["estimator_options"] == "given"


def test_the_choice_is_said(files: list[str], tmp_path: Path,
                           capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fit", *files[:2], "--out", str(tmp_path / "c.json"), "--no-validation"]) == 0
    err = capsys.readouterr().err
    assert "note: estimator from the temperature readout of 2 run(s): refresh 1.28" in err
    assert "regressed on the chamber temperature" in err


@pytest.fixture(scope="module")
def two_imus(files: list[str], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One CSV, two IMUs: A the generator's readout (0.125 °C), B the same runs read at
    0.5 °C."""
    from gyrotherm.codecs import read_run

    lines = ["t,temp,gx,dev,seg"]
    for dev, lsb in (("A", None), ("B", 0.5)):
        for f in files[:2]:
            run = read_run(f)
            temp = run.temperature_c if lsb is None else np.round(run.temperature_c / lsb) * lsb
            lines += [f"{t:.17g},{c:.17g},{g:.17g},{dev},{run.name}"
                      for t, c, g in zip(run.time_s, temp, run.rates_dps["x"], strict=True)]
    log = tmp_path_factory.mktemp("two_imus") / "two_imus.csv"
    log.write_text("\n".join(lines) + "\n")
    return log


TWO_IMU_COLUMNS = ["--columns", "time=t:s", "temperature=temp:degC", "x=gx:dps",
                   "device=dev", "run=seg", "--no-validation"]


def test_each_device_of_a_log_gets_its_own_readouts_estimator(two_imus: Path,
                                                              tmp_path: Path) -> None:
    # each calibration of 'fit --out DIR' must be the one 'fit --device ID' writes (the
    # estimator once came from the median over both devices' runs: LSB of neither)
    log, cols = two_imus, TWO_IMU_COLUMNS
    assert main(["-q", "fit", str(log), "--out", str(tmp_path / "all") + "/", *cols]) == 0
    lsbs = {}
    for dev in ("A", "B"):
        assert main(["-q", "fit", str(log), "--device", dev, "--out",
                     str(tmp_path / f"{dev}.json"), *cols]) == 0
        alone = json.loads((tmp_path / f"{dev}.json").read_text())
        both = json.loads((tmp_path / "all" / f"{dev}.json").read_text())
        assert both["estimator"] == alone["estimator"], dev
        assert both["coefficients"] == alone["coefficients"], dev
        assert both["provenance"]["estimator_chosen"]["runs"] == 2
        lsbs[dev] = both["estimator"]["quantisation_c"]
    assert lsbs == pytest.approx({"A": 0.125, "B": 0.5}, rel=1e-6)


def test_a_damaged_logs_note_is_said_once_though_fit_reads_it_twice(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = (Path(__file__).parents[1] / "data" / "px4_two_gyros.ulg").read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(data[:-7])  # a last message cut short
    main(["-q", "fit", str(cut), "--out", str(tmp_path / "c.json"), "--rest", "all",
          "--force", "--model", "t2"])  # too short to fit: the note is what is checked
    err = capsys.readouterr().err
    assert err.count("the log is cut short") == 1, err


def test_with_several_devices_each_choice_names_its_device(
        two_imus: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fit", str(two_imus), "--out", f"{tmp_path}/", *TWO_IMU_COLUMNS]) == 0
    err = capsys.readouterr().err
    for dev in ("A", "B"):
        assert f"note: device {dev}: estimator from the temperature readout of 2 run(s)" in err
        assert f"note: device {dev}: method offsets:" in err


def test_the_method_auto_resolved_is_in_the_provenance(both: tuple[dict, dict], files: list[str],
                                                       tmp_path: Path) -> None:
    fit, _ = both
    chosen = fit["provenance"]["method_chosen"]
    assert chosen["rule"] == "--method auto" and chosen["offsets_from_share"] == 0.5
    assert 0.5 <= chosen["within_run_share"] <= 1.0  # warm-ups: offsets, as recorded
    out = tmp_path / "given.json"
    assert main(["-q", "fit", *files[:2], "--out", str(out), "--no-validation",
                 "--method", "offsets"]) == 0
    given = json.loads(out.read_text())["provenance"]
    assert given["method"] == "offsets" and "method_chosen" not in given


def test_runs_without_a_device_id_beside_devices_are_named_so(
        two_imus: Path, files: list[str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    # a run file without a device column beside a two-IMU log: three calibrations; the
    # notes once said 'device : ...' for it
    assert main(["fit", str(two_imus), files[2], "--out", f"{tmp_path}/",
                 *TWO_IMU_COLUMNS]) == 0
    err = capsys.readouterr().err
    assert "note: device : " not in err
    assert "note: the runs without a device id: estimator from the temperature readout" in err
    assert "note: the runs without a device id: method offsets" in err
