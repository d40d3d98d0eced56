"""``gyrotherm sim life`` then ``gyrotherm learn``, as a newcomer without a chamber would
try it: the power-ons written are the simulator's (:func:`gyrotherm.sim._life.life`, the
same ambients and seeds), and what ``learn`` writes from them is closer to the simulator's
true bias than no compensation on power-ons it never saw (another seed). Bad options are
named."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrotherm.cli import main
from gyrotherm.codecs import read_run
from gyrotherm.compensation import features, load_calibration
from gyrotherm.compensation._learn import warmup_rows
from gyrotherm.sim._life import ambients


def test_sim_life_then_learn_beats_no_compensation_on_unseen_power_ons(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    life = tmp_path / "life"
    assert main(["sim", "life", "--power-ons", "5", "--out", str(life), "--seed", "3",
                 "--json"]) == 0
    files = json.loads(capsys.readouterr().out)["runs"]
    assert len(files) == 5 and all(f["rows"] == 6001 for f in files)
    for f, ambient in zip(files, ambients(5, seed=3), strict=True):
        run = read_run(f["path"])
        assert run.time_s[0] == 0.0  # from the power-on, as a log from boot
        assert run.metadata["ambient_c"] == f"{ambient:.3f}"
    cal_path = tmp_path / "learnt.cal.json"
    assert main(["learn", *sorted(str(p) for p in life.glob("*.csv")),
                 "--out", str(cal_path)]) == 0
    cal = load_calibration(cal_path)
    held = tmp_path / "held"
    assert main(["sim", "life", "--power-ons", "3", "--out", str(held), "--seed", "77",
                 "--ambient-c", "0", "30"]) == 0
    for path in sorted(held.glob("*.csv")):
        f = features(read_run(path), cal.estimator)
        use = warmup_rows(f)
        for a in ("x", "y", "z"):
            b = cal.bias_series(a, f.temperature_c, f.delta_t_c, f.time_s)[0]
            err = (b - f.true_bias_dps[a])[use]
            truth = f.true_bias_dps[a][use]
            assert np.std(err) < 0.25 * np.std(truth), (path.name, a)


@pytest.mark.parametrize(("args", "needle"), [
    (["--ambient-c", "30", "10"], "--ambient-c: expected LO ≤ HI"),
    (["--warmup-s", "0"], "--warmup-s: expected > 0"),
    (["--power-ons", "0"], "--power-ons: at least 1"),
])
def test_bad_options_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                               args: list[str], needle: str) -> None:
    assert main(["sim", "life", "--out", str(tmp_path / "o"), *args]) == 2
    assert needle in capsys.readouterr().err
