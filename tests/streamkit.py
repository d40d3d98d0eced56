"""Test helpers for the streaming path: frames from a run, a recording sink, free ports."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import can

from gyrotherm.codecs import FrameEncoder, RateSample, Run, TemperatureSample


def run_frames(run: Run, encoder: FrameEncoder, *, period_s: float = 0.0) -> Iterator[can.Message]:
    """Temperature frame (when due, as the offline estimator feeds rows) then rate frame."""
    last = -1e18
    for i, t in enumerate(run.time_s.tolist()):
        if t - last >= period_s - 1e-9:
            last = t
            yield encoder.encode_temperature(TemperatureSample(t, float(run.temperature_c[i])))
        r = run.rates_dps
        yield encoder.encode_rate(RateSample(t, float(r["x"][i]), float(r["y"][i]),
                                             float(r["z"][i])))


class RecordingSink:
    def __init__(self) -> None:
        self.rates: list[bytes] = []
        self.states: list[bytes] = []

    def put_rate(self, payload: bytes) -> None:
        self.rates.append(payload)

    def put_state(self, payload: bytes) -> None:
        self.states.append(payload)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port
