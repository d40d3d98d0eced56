"""Several simulated gyros on one bus (`sim stream --gyros N`): own ids, own physics."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from gyrotherm.codecs import FrameDecoder, RateSample, read_candump
from gyrotherm.sim import ChamberProfile, simulate
from gyrotherm.sim._gyros import gyro_params, gyro_signal_map, several_gyros


def test_each_gyro_has_its_ids_and_its_bias() -> None:
    runs = [simulate(ChamberProfile.from_pairs([(0.0, 10.0), (2.0, 10.0)]), name=f"g{k}",
                     gyro=gyro_params(k).quiet(), rate_hz=50.0, seed=k) for k in range(3)]
    frames = list(several_gyros(runs))
    assert [m.timestamp for m in frames] == sorted(m.timestamp for m in frames)
    means = []
    for k in range(3):
        decoder = FrameDecoder(signal_map=gyro_signal_map(k))
        got = [r for r in map(decoder.decode, frames) if isinstance(r, RateSample)]
        assert len(got) == len(runs[k])  # its own frames, no other gyro's
        assert decoder.layout.rate.frame_id == 0x120 + 2 * k
        np.testing.assert_allclose([r.rate_x_dps for r in got], runs[k].rates_dps["x"],
                                   atol=0.001)
        means.append(float(np.mean(runs[k].rates_dps["x"])))
    assert len({round(m, 3) for m in means}) == 3  # three bias curves


def test_sim_stream_gyros_option(tmp_path: Path) -> None:
    log = tmp_path / "g.log"
    out = subprocess.run([sys.executable, "-m", "gyrotherm", "sim", "stream", "--gyros", "3",
                          "--chamber", "0.1", "--hold-s", "1", "--rate-hz", "20", "--speed", "0",
                          "--interface", "none", "--write-candump", str(log)],
                         capture_output=True, text=True, check=True).stdout
    ids = {m.arbitration_id for m in read_candump(log)}
    assert ids == {0x120, 0x121, 0x122, 0x123, 0x124, 0x125}, out
