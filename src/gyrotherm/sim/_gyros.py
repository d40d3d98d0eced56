"""Several simulated gyros on one bus: own physics, own seeds, own CAN ids.

Gyro ``k`` (0, 1, …) of :func:`several_gyros`:

* **physics**: :func:`gyro_params` — the base gyro's true bias with every coefficient
  scaled by ``1 + 0.2·k`` and the constant term shifted by ``+0.1·k`` °/s on x,
  ``−0.1·k`` on y (so no two gyros share a bias curve), the base noise levels;
* **noise and switch-on offset**: its own seed, ``seed + k``;
* **CAN ids**: :func:`gyro_signal_map` — the DBC's rate and temperature ids + ``2·k``
  (the shipped gyro.dbc: 0x120/0x121, 0x122/0x123, 0x124/0x125 …), as a daemon
  configuration names them with ``signals = { rate_frame_id = …,
  temperature_frame_id = … }`` in each ``[[imu]]`` table.

The streams are merged in time order (at equal times gyro 0 first), so the gyros
run side by side on the bus as the IMUs of one vehicle do.
"""

from __future__ import annotations

import dataclasses
import heapq
from collections.abc import Iterator, Sequence

import can

from gyrotherm._errors import ConfigError
from gyrotherm.codecs import DEFAULT_DBC_PATH, FrameEncoder, Run, SignalMap
from gyrotherm.codecs._canmap import resolve_layout
from gyrotherm.sim._gyro import BiasTruth, GyroParams
from gyrotherm.sim._runframes import FrameStream, frames_from_run

#: Most gyros one stream plays (ids + 2·k must stay distinct from other traffic).
MAX_GYROS = 16


def gyro_signal_map(index: int, *, dbc_path: str = str(DEFAULT_DBC_PATH),
                    base: SignalMap | None = None) -> SignalMap:
    """Gyro ``index``'s signal map: ``base``'s messages at the DBC's ids + 2·index."""
    base = base or SignalMap.default()
    if index == 0:
        return base
    layout = resolve_layout(dbc_path, base)
    return dataclasses.replace(base, rate_frame_id=layout.rate.frame_id + 2 * index,
                               temperature_frame_id=layout.temperature.frame_id + 2 * index)


def gyro_params(index: int, base: GyroParams | None = None) -> GyroParams:
    """Gyro ``index``'s physics (module docstring); gyro 0 is ``base`` unchanged."""
    base = base or GyroParams()
    if index == 0:
        return base
    scale, shift = 1.0 + 0.2 * index, {"x": 0.1 * index, "y": -0.1 * index}
    coeffs = {axis: {term: c * scale + (shift.get(axis, 0.0) if term == "1" else 0.0)
                     for term, c in terms.items()}
              for axis, terms in base.bias.coefficients.items()}
    return dataclasses.replace(base, bias=BiasTruth(base.bias.model, coeffs))


class _Merged(FrameStream):
    def __init__(self, streams: Sequence[FrameStream]) -> None:
        kinds: dict[int, int] = {}
        for s in streams:
            kinds.update(s.kinds)
        super().__init__((), kinds=kinds)
        self.streams = tuple(streams)
        self._it = self._merge()

    def _merge(self) -> Iterator[can.Message]:
        tagged = [((m.timestamp, k, m) for m in s) for k, s in enumerate(self.streams)]
        for _, k, msg in heapq.merge(*tagged, key=lambda x: (x[0], x[1])):
            stream = self.streams[k]
            self.last_saturated = stream.last_saturated
            self.saturated = sum(s.saturated for s in self.streams)
            yield msg


def several_gyros(runs: Sequence[Run], *, dbc_path: str = str(DEFAULT_DBC_PATH),
                  temperature_period_s: float | None = None) -> FrameStream:
    """The runs of gyros 0, 1, … as one time-ordered frame stream, gyro k at its own ids."""
    if not 1 <= len(runs) <= MAX_GYROS:
        raise ConfigError(f"gyros: between 1 and {MAX_GYROS}, got {len(runs)}")
    streams = [frames_from_run(run, encoder=FrameEncoder(dbc_path, gyro_signal_map(
        k, dbc_path=dbc_path)), temperature_period_s=temperature_period_s)
        for k, run in enumerate(runs)]
    return streams[0] if len(streams) == 1 else _Merged(streams)
