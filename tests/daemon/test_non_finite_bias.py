"""The daemon never turns a finite raw rate into a non-finite corrected one."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from gyrotherm.codecs import FrameDecoder, FrameEncoder, RateSample, TemperatureSample
from gyrotherm.codecs._wire import StatusFlags
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration
from gyrotherm.compensation._models import Scaling
from gyrotherm.daemon import Pipeline
from streamkit import RecordingSink


def _broken(cal: Calibration, how: str) -> Calibration:
    if how == "scaling":  # a valid-looking file: x = (T − t_ref)/1e-300, x**2 overflows
        return replace(cal, scaling=Scaling(cal.scaling.t_ref_c, 1e-300, cal.scaling.dt_scale_c))
    # coefficients at the float limit: at T clamped to t_max (x = 1) the sum overflows
    k = len(cal.model.terms)
    return replace(cal, coefficients={a: (1e308,) * k for a in cal.axes})


@pytest.mark.parametrize("how", ["scaling", "coefficients"])
def test_a_non_finite_bias_gives_bias_zero_and_bias_invalid(
    stream_calibration: Calibration, how: str
) -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=_broken(stream_calibration, how))
    for k in range(30):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 80.0)), 0.0)
        pipe.process(enc.encode_rate(RateSample(float(k), 0.1, -0.2, 0.3)), 0.0)
    assert 80.0 > stream_calibration.valid_range.t_max_c  # T clamped: x = 1
    assert pipe.counters().drops == {}  # no internal_error
    for payload in sink.rates:
        msg = decode_rate(payload)
        assert msg.bias_dps == (0.0, 0.0, 0.0)
        assert msg.rate_dps == msg.raw_rate_dps == pytest.approx((0.1, -0.2, 0.3))
        assert all(math.isfinite(v) for v in msg.rate_dps)
        assert msg.flags & StatusFlags.BIAS_INVALID
        assert not msg.flags & StatusFlags.NON_FINITE
    assert decode_state(sink.states[-1]).flags & StatusFlags.BIAS_INVALID


def test_a_sane_calibration_never_sets_bias_invalid(stream_calibration: Calibration) -> None:
    enc = FrameEncoder()
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=stream_calibration)
    for k in range(30):
        pipe.process(enc.encode_temperature(TemperatureSample(float(k), 20.0)), 0.0)
        pipe.process(enc.encode_rate(RateSample(float(k), 0.1, -0.2, 0.3)), 0.0)
    msgs = [decode_rate(p) for p in sink.rates]
    assert not any(m.flags & StatusFlags.BIAS_INVALID for m in msgs)
    assert any(m.bias_dps != (0.0, 0.0, 0.0) for m in msgs)
