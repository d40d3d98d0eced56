"""The daemon's ``[learn]`` table: learning a calibration in the field (opt-in).

Off by default: on when the table is present (as ``[zero]``), unless ``enabled =
false``. Every key is optional; defaults::

    [learn]
    enabled = true
    margin_frac = 0.10        # the learnt model's held-out bias error must be
                              # ≤ (1 − margin_frac) × the current one's (0 … 0.9)
    min_warmups = 3           # warm-ups at rest before anything is adopted (3 … 256)
    min_span_c = 8.0          # spread of the warm-ups' start temperatures, °C (1 … 100)
    warmup_window_s = 900.0   # a warm-up is collected this long after power-on, s
                              # (70 … 1800)
    min_rest_s = 60.0         # at-rest time a warm-up needs to count, s (10 … 1800)
    rest_window_s = 5.0       # rest is judged on blocks of this length, s (0.5 … 60)
    max_rate_dps = 5.0        # a rate frame with |ω| above this is motion, °/s (0.1 … 100)
    max_std_dps = 0.5         # a block whose rate std (any axis) is above this is
                              # motion, °/s (0.001 … 10)

It needs ``state_dir`` (the learnt statistics and the adopted calibration live there)
and ``[zero]``: the held-out validation (:func:`~gyrotherm.compensation._learn.decide`)
removes each warm-up's own offset, so it checks the *shape* of the learnt bias, never
its level (the mean of the power-ons' switch-on offsets, and of what the curvature terms
make of the differing ambients). On the simulated vehicle life, 5 power-ons: with the
boot-time zero the learnt calibration leaves 0.004–0.03 °/s of bias error (0.03–0.30 °/s
uncompensated); without it 0.02–0.53 °/s, worse than nothing on some axes.
With ``[[imu]]`` tables, a top-level ``[learn]`` applies to every IMU and an IMU's own
``learn = { … }`` overrides its keys (``learn = { enabled = false }`` leaves that IMU
out). Errors are :class:`gyrotherm.ConfigError` naming the file, the key and the value.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from gyrotherm._errors import ConfigError
from gyrotherm.compensation._learn_gates import ADOPT_MARGIN, GATES, SETTLE_S, WARMUP_MAX_S

#: (lowest, highest) accepted per key; integers for ``min_warmups``.
LIMITS: dict[str, tuple[float, float]] = {
    "margin_frac": (0.0, 0.9),
    "min_warmups": (int(GATES["min_warmups"]), 256),
    "min_span_c": (1.0, 100.0),
    "warmup_window_s": (SETTLE_S + 60.0, WARMUP_MAX_S),
    "min_rest_s": (10.0, WARMUP_MAX_S),
    "rest_window_s": (0.5, 60.0),
    "max_rate_dps": (0.1, 100.0),
    "max_std_dps": (1e-3, 10.0),
}


@dataclass(frozen=True)
class LearnConfig:
    """Validated ``[learn]`` settings (module docstring)."""

    margin_frac: float = ADOPT_MARGIN
    min_warmups: int = int(GATES["min_warmups"])
    min_span_c: float = float(GATES["min_start_span_c"])
    warmup_window_s: float = 900.0
    min_rest_s: float = 60.0
    rest_window_s: float = 5.0
    max_rate_dps: float = 5.0
    max_std_dps: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            lo, hi = LIMITS[f.name]
            v = getattr(self, f.name)
            integer = f.name == "min_warmups"
            if isinstance(v, bool) or not isinstance(v, int if integer else (int, float)):
                kind = "an integer" if integer else "a number"
                raise ConfigError(f"learn.{f.name} = {v!r}: expected {kind}")
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ConfigError(f"learn.{f.name} = {v!r} is outside [{lo:g}, {hi:g}]")
            object.__setattr__(self, f.name, int(v) if integer else float(v))
        if self.min_rest_s > self.warmup_window_s - SETTLE_S:
            raise ConfigError(f"learn.min_rest_s = {self.min_rest_s:g} s cannot fit in "
                              f"warmup_window_s = {self.warmup_window_s:g} s minus the "
                              f"estimator's settling {SETTLE_S:g} s")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str = "[learn]"
                  ) -> LearnConfig | None:
        """From a TOML table (present: on); None when ``enabled = false``."""
        known = {f.name for f in fields(cls)} | {"enabled"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {unknown}; known: {sorted(known)}")
        enabled = data.get("enabled", True)
        if not isinstance(enabled, bool):
            raise ConfigError(f"{where}: enabled = {enabled!r}: expected true or false")
        try:
            cfg = cls(**{k: v for k, v in data.items() if k != "enabled"})
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from exc
        return cfg if enabled else None

    def to_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


__all__ = ["LIMITS", "LearnConfig"]
