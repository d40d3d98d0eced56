"""Test helpers for the daemon's [learn] mode: a "boot" of one IMU's pipeline with its
learner on a state directory, simulated power-ons fed as CAN frames (the wall clock
advancing with the sensor's: a silence or jump the tests want is in the stamps alone)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import can
import numpy as np

from gyrotherm.codecs import FrameDecoder, FrameEncoder, Run
from gyrotherm.codecs._wire import StateMessage
from gyrotherm.codecs._wire_decode import decode_rate, decode_state
from gyrotherm.compensation import Calibration, ZeroConfig
from gyrotherm.daemon import Pipeline
from gyrotherm.daemon._learn_config import LearnConfig
from gyrotherm.daemon._learner import Learner
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.sim._life import LIFE_GYRO
from streamkit import RecordingSink, run_frames

EST = EstimatorConfig(tau_s=LIFE_GYRO.tau_s)
#: Wall clock at sensor time 0 (the receive time of a frame = WALL0 + its stamp).
WALL0 = 1.7e9
CONFIG = LearnConfig(min_rest_s=60.0, warmup_window_s=900.0)


@dataclass
class Boot:
    """One daemon start for one IMU: its pipeline, learner and recorded messages."""

    pipeline: Pipeline
    learner: Learner
    sink: RecordingSink
    calibration_id: str

    def feed(self, frames: Iterable[can.Message], *, wall_offset_s: float = 0.0) -> None:
        for msg in frames:
            self.pipeline.process(msg, WALL0 + wall_offset_s + msg.timestamp)

    def states(self) -> list[StateMessage]:
        return [decode_state(p) for p in self.sink.states]

    def rates(self) -> np.ndarray:
        return np.array([decode_rate(p).rate_dps for p in self.sink.rates])

    def stop(self) -> None:
        self.learner.shutdown()


def boot(state_dir: Path, *, sensor: str = "imu0", configured: Calibration | None = None,
         configured_id: str = "", config: LearnConfig = CONFIG,
         zero: ZeroConfig | None = None) -> Boot:
    """Start an IMU as ImuChannel does: the learner reads state_dir and says which
    calibration to run with; an adoption swaps the pipeline's calibration. ``zero``: the
    boot-time zero, which removes each power-on's level (the learner validates the
    shape of the bias within warm-ups; their levels are the switch-on offsets)."""
    learner = Learner(config, vehicle="car", sensor=sensor, state_dir=state_dir,
                      power_on_gap_s=30.0, estimator=EST, background=False)
    cal, cid = learner.start(configured, configured_id)
    sink = RecordingSink()
    pipe = Pipeline(FrameDecoder(), sink, calibration=cal, estimator=EST, zero=zero)
    pipe.attach_learner(learner)
    b = Boot(pipe, learner, sink, cid)

    def adopt(c: Calibration, i: str) -> None:
        pipe.set_calibration(c)
        b.calibration_id = i

    learner.on_adopt = adopt
    return b


def frames(run: Run, *, shift_s: float = 0.0) -> list[can.Message]:
    """The run's CAN frames (temperature then rate per row), stamps shifted by ``shift_s``."""
    if shift_s:
        run = replace(run, time_s=run.time_s + shift_s)
    return list(run_frames(run, FrameEncoder()))


def life_of(state_dir: Path, runs: Iterable[Run], **kw: object) -> list[Boot]:
    """Each run a power-on of its own daemon start (a vehicle's power cycle restarts both),
    stopped at its end."""
    boots = []
    for run in runs:
        b = boot(state_dir, **kw)  # type: ignore[arg-type]
        b.feed(frames(run))
        b.stop()
        boots.append(b)
    return boots
