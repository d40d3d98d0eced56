"""``gyrotherm fleet`` writes, for each IMU, the calibration ``gyrotherm fit`` writes from
that IMU's logs: the estimator chosen from the IMU's own temperature readout, the method
from its runs (issue 19, item 4: one estimator rule on every path). Two IMUs of the
independent generator (``analysis.synth``) with different readouts, 0.125 °C refreshed
every 1.28 s and 1 °C every 0.5 s: the truth the chosen LSB and refresh are checked against."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from gyrotherm.analysis import SynthConfig
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.cli import main
from gyrotherm.codecs import write_run

IMUS = {("veh-a", "imu-1", "imu-1"): SynthConfig(duration_s=3000.0, rate_hz=10.0),
        ("veh-b", "imu-2", "imu-2"): SynthConfig(duration_s=3000.0, rate_hz=10.0,
                                                 readout_lsb_c=1.0, readout_period_s=0.5)}


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str, str], list[str]]:
    d = tmp_path_factory.mktemp("fleet-est")
    out = {}
    for i, (key, cfg) in enumerate(IMUS.items()):
        runs, _ = variant_runs(cfg, shapes={}, n_runs=3, seed=40 + i)
        ids = dict(zip(("vehicle_id", "device_id", "sensor_id"), key, strict=True))
        out[key] = [str(write_run(replace(r, name=f"{key[0]}-{r.name}",
                                          metadata={**r.metadata, **ids}),
                                  d / f"{key[0]}-{r.name}.csv")) for r in runs]
    return out


@pytest.fixture(scope="module")
def written(logs: dict[tuple[str, str, str], list[str]], tmp_path_factory: pytest.TempPathFactory
            ) -> dict[tuple[str, str, str], tuple[dict, dict]]:
    d = tmp_path_factory.mktemp("cals")
    every = [f for files in logs.values() for f in files]
    assert main(["-q", "fleet", *every, "--out", str(d / "fleet")]) == 0
    pairs = {}
    for key, files in logs.items():
        fit_path = d / f"fit-{key[0]}.json"
        assert main(["-q", "fit", *files, "--out", str(fit_path), "--no-validation"]) == 0
        fleet_path = d / "fleet" / f"{key[0]}-{key[1]}.json"
        pairs[key] = (json.loads(fit_path.read_text()), json.loads(fleet_path.read_text()))
    return pairs


def test_each_imu_gets_fits_calibration(
        written: dict[tuple[str, str, str], tuple[dict, dict]]) -> None:
    for fit, fleet in written.values():
        for key in ("model", "estimator", "scaling", "range"):
            assert fleet[key] == fit[key], key
        for axis, coefs in fit["coefficients"].items():
            assert fleet["coefficients"][axis] == pytest.approx(coefs, rel=1e-9, abs=1e-12)
        assert fleet["provenance"]["estimator_chosen"] == fit["provenance"]["estimator_chosen"]
        assert fleet["provenance"]["method_chosen"] == fit["provenance"]["method_chosen"]


def test_each_imu_its_own_readout(
        written: dict[tuple[str, str, str], tuple[dict, dict]]) -> None:
    for key, (_, fleet) in written.items():
        cfg = IMUS[key]
        est = fleet["estimator"]
        assert est["quantisation_c"] == pytest.approx(cfg.readout_lsb_c, rel=0.10)
        assert est["update_period_s"] == pytest.approx(cfg.readout_period_s, rel=0.10)


def test_an_estimator_option_is_used_for_every_imu(
        logs: dict[tuple[str, str, str], list[str]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """With an estimator option, every IMU takes the options (the others their
    defaults), as fit does: the 0.125 °C IMU is fitted with τ 200 s; the 1 °C one,
    estimated as if it read 0.125 °C every 1 s, is refused by the conditioning gate,
    which the readout's own estimator passes (the test above)."""
    every = [f for files in logs.values() for f in files]
    capsys.readouterr()
    assert main(["-q", "fleet", *every, "--out", str(tmp_path), "--tau-s", "200",
                 "--json"]) == 0
    imus = {i["vehicle_id"]: i for i in json.loads(capsys.readouterr().out)["imus"]}
    cal = json.loads((tmp_path / "veh-a-imu-1.json").read_text())
    assert cal["estimator"]["tau_s"] == 200.0
    assert cal["provenance"]["estimator_options"] == "given"
    assert "estimator_chosen" not in cal["provenance"]
    assert imus["veh-b"]["status"] == "not fitted"
    assert "conditioning" in imus["veh-b"]["reason"]


def test_a_previous_calibration_with_another_estimator_is_said(
        logs: dict[tuple[str, str, str], list[str]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Drift scores the previous calibration on T/ΔT estimated with the new one's
    estimator; when the previous one's was another, the entry says so."""
    files = logs[("veh-a", "imu-1", "imu-1")]
    assert main(["-q", "fleet", *files, "--out", str(tmp_path / "given"), "--tau-s", "200"]) == 0
    assert main(["-q", "fleet", *files, "--out", str(tmp_path / "auto")]) == 0
    for previous, differs in (("given", True), ("auto", False)):
        capsys.readouterr()
        assert main(["-q", "fleet", *files, "--previous", str(tmp_path / previous),
                     "--json"]) == 0
        (imu,) = json.loads(capsys.readouterr().out)["imus"]
        assert imu["previous"] and imu["previous_estimator_differs"] is differs
