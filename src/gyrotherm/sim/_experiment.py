"""Tang et al.'s chamber experiment (§4.3) as profiles and simulated runs.

Chamber soaked at −20 °C, gyro switched on, 1 h hold; ramp to 50 °C over the
heating time (5, 10, 20, 30, 40, 50 or 60 min); 1 h hold. The paper's
validation run is a separate 60-min heating run.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from gyrotherm.codecs import Run
from gyrotherm.sim._chamber import ChamberModel, ChamberProfile
from gyrotherm.sim._gyro import GyroParams, simulate

PAPER_HEATING_MIN: tuple[int, ...] = (5, 10, 20, 30, 40, 50, 60)
COLD_C = -20.0
HOT_C = 50.0


def heating_profile(
    heating_min: float,
    *,
    cold_c: float = COLD_C,
    hot_c: float = HOT_C,
    hold_before_s: float = 3600.0,
    hold_after_s: float = 3600.0,
) -> ChamberProfile:
    """Soak at ``cold_c``, ramp to ``hot_c`` over ``heating_min`` minutes, hold."""
    ramp_end = hold_before_s + heating_min * 60.0
    return ChamberProfile.from_pairs(
        [(0.0, cold_c), (hold_before_s, cold_c), (ramp_end, hot_c),
         (ramp_end + hold_after_s, hot_c)]
    )


def run_name(heating_min: float, *, validation: bool = False) -> str:
    return f"{'valid' if validation else 'heat'}-{heating_min:02g}min"


def chamber_runs(
    heating_min: Sequence[float] = PAPER_HEATING_MIN,
    *,
    seed: int = 0,
    rate_hz: float = 10.0,
    gyro: GyroParams | None = None,
    chamber: ChamberModel | None = None,
    hold_s: float = 3600.0,
    validation: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[Run]:
    """One simulated run per heating time; run i uses seed ``seed·1000 + i``.

    ``validation`` names the runs ``valid-…`` and offsets the seeds so they
    never coincide with the fitting runs.
    """
    out = []
    base = seed * 1000 + (500 if validation else 0)
    for i, minutes in enumerate(heating_min):
        profile = heating_profile(minutes, hold_before_s=hold_s, hold_after_s=hold_s)
        out.append(simulate(
            profile,
            name=run_name(minutes, validation=validation),
            gyro=gyro,
            chamber=chamber,
            rate_hz=rate_hz,
            seed=base + i,
            metadata={"heating_min": f"{minutes:g}", "experiment": "tang2013-chamber"},
        ))
        if progress:
            progress(i + 1, len(heating_min))
    return out
