"""The diagnosis' unexplained correction on the vehicle (issue 19, item 3).

Training: 4 runs of one simulated device with an off-catalogue bias step in temperature
(the independent generator's ``bias_step``), diagnosed, ``diagnose --calibration``'s
export writing the step as the x axis' ``correction``. Held out: a 5th run of the same
device, never seen by the fit, streamed through the daemon's pipeline as CAN frames.

* parity: the daemon's corrected rates equal offline compensation (the compensator's
  series on the offline estimator) to 1e-9 °/s, with the correction in the calibration;
* deployed gain, one quantity offline and deployed (scripts/correction_gain.py's design):
  the same calibration without / with the correction applied to the held-out run offline
  (``removed_bias`` on its offline features) and by the daemon (the bias each rate message
  removed), both scored as the bias error against the generator's truth on the same rows
  (not flagged ESTIMATOR_WARMUP), the error's mean removed (the switch-on offset is the
  boot-time zero's job); the deployed gain ≥ 80 % of the offline gain. Seed fixed before
  any result was seen.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gyrotherm.analysis import SynthConfig, diagnose
from gyrotherm.analysis._diagnose import export_calibration
from gyrotherm.analysis.synth._variants import variant_runs
from gyrotherm.codecs import (
    FrameDecoder,
    FrameEncoder,
    RateMessage,
    RateSample,
    Run,
    StatusFlags,
)
from gyrotherm.codecs._wire_decode import decode_rate
from gyrotherm.compensation import Calibration, features, removed_bias
from gyrotherm.daemon import Pipeline
from streamkit import RecordingSink, assert_offline_compensation, run_frames

CFG = SynthConfig(duration_s=6000.0, rate_hz=10.0)
SEED = 23


@pytest.fixture(scope="module")
def trained() -> tuple[Calibration, Run]:
    runs, _ = variant_runs(CFG, shapes={"bias_step": {"at_c": 30.0}}, n_runs=5, seed=SEED)
    train, held = runs[:4], runs[4]
    zero = np.zeros(len(held))  # the generator's gyro has one axis; the frames carry three
    held = _as_framed(replace(held, rates_dps={**held.rates_dps, "y": zero, "z": zero}))
    d = diagnose(train, simulate=False)
    assert [u.variable for u in d.unexplained] == ["temperature_c"]
    return export_calibration(train, d).calibration, held


def _as_framed(run: Run) -> Run:
    """``run`` as the frames carry it (the DBC's resolution), for the offline reference."""
    decoder = FrameDecoder()
    rates, temps = [], []
    for msg in run_frames(run, FrameEncoder()):
        sample = decoder.decode(msg)
        (rates if isinstance(sample, RateSample) else temps).append(sample)
    assert len(rates) == len(temps) == len(run)
    return replace(run, temperature_c=np.array([t.temperature_c for t in temps]),
                   rates_dps={a: np.array([getattr(r, f"rate_{a}_dps") for r in rates])
                              for a in "xyz"})


def _stream(cal: Calibration, run: Run) -> list[RateMessage]:
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal)  # type: ignore[arg-type]
    for msg in run_frames(run, FrameEncoder()):
        pipe.process(msg, 1.0e9)
    assert pipe.counters().drops == {}
    return [decode_rate(p) for p in sink.rates]


def _bias_error_rms(removed: np.ndarray, run: Run, rows: np.ndarray) -> float:
    """RMS of (bias removed − truth) on ``rows``, the error's mean taken out."""
    err = (removed - run.true_bias_dps["x"])[rows]
    return float(np.sqrt(np.mean((err - err.mean()) ** 2)))


def test_daemon_applies_the_correction_as_offline_compensation(
    trained: tuple[Calibration, Run],
) -> None:
    cal, held = trained
    assert cal.effect_names("x") == ("correction",)
    assert_offline_compensation([m.rate_dps for m in _stream(cal, held)], held, cal)


def test_deployed_gain_on_a_held_out_run_is_at_least_80_percent_of_offline(
    trained: tuple[Calibration, Run],
) -> None:
    cal, held = trained
    cals = {"without": replace(cal, effects={"x": replace(cal.effects_of("x"),
                                                          correction=None)}),
            "with": cal}
    assert cals["without"].effect_names("x") == ()
    feats = features(held, cal.estimator)
    msgs = {k: _stream(c, held) for k, c in cals.items()}
    rows = np.array([not (m.flags & StatusFlags.ESTIMATOR_WARMUP) for m in msgs["with"]])
    assert rows.sum() > 0.99 * len(held)
    offline = {k: _bias_error_rms(removed_bias(c, feats).bias["x"][0], held, rows)
               for k, c in cals.items()}
    deployed = {k: _bias_error_rms(np.array([m.bias_dps[0] for m in v]), held, rows)
                for k, v in msgs.items()}
    offline_gain = offline["without"] / offline["with"]
    deployed_gain = deployed["without"] / deployed["with"]
    assert cal.provenance["effects_fit"]["x"]["correction"]["gain"] > 1.1  # the export's LORO
    assert offline_gain > 1.5
    assert deployed_gain >= 0.8 * offline_gain, (deployed_gain, offline_gain)
