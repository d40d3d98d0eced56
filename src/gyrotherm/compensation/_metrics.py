"""Error metrics in the style of Tang et al.'s Table 2 (all in °/s).

For a static gyro the true rate is 0, so the error of the raw output is the
output itself and the error after compensation is ``raw − bias``. For a
residual series e_i (i = 1..n):

* ``mean_dps``    = (1/n) Σ e_i                  — the paper's "average error";
* ``rms_dps``     = √((1/n) Σ e_i²)              — root mean square; the paper's
  "mean square error" figures (0.043–0.060 °/s for residuals of a few 0.01 °/s)
  read as this root, not as the mean of squares;
* ``std_dps``     = √((1/n) Σ (e_i − mean)²);
* ``max_abs_dps`` = max |e_i|.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class ErrorMetrics:
    """Summary of a residual series, °/s."""

    mean_dps: float
    rms_dps: float
    std_dps: float
    max_abs_dps: float
    n: int

    @classmethod
    def of(cls, residual_dps: NDArray[np.float64]) -> ErrorMetrics:
        e = np.asarray(residual_dps, dtype=np.float64)
        if e.size == 0:
            nan = float("nan")
            return cls(nan, nan, nan, nan, 0)
        return cls(
            mean_dps=float(np.mean(e)),
            rms_dps=float(np.sqrt(np.mean(e * e))),
            std_dps=float(np.std(e)),
            max_abs_dps=float(np.max(np.abs(e))),
            n=int(e.size),
        )

    def to_dict(self) -> dict[str, float | int]:
        return {
            "mean_dps": self.mean_dps,
            "rms_dps": self.rms_dps,
            "std_dps": self.std_dps,
            "max_abs_dps": self.max_abs_dps,
            "n": self.n,
        }


@dataclass(frozen=True)
class RunScore:
    """Raw vs compensated errors of one run on one axis.

    ``truth`` scores the estimated bias against the simulator's true bias
    (only when the run carries ``true_bias_<axis>_dps``).
    """

    run: str
    axis: str
    raw: ErrorMetrics
    compensated: ErrorMetrics
    truth: ErrorMetrics | None
    clamped_fraction: float

    def to_dict(self) -> dict[str, object]:
        return {
            "run": self.run,
            "axis": self.axis,
            "raw": self.raw.to_dict(),
            "compensated": self.compensated.to_dict(),
            "truth": None if self.truth is None else self.truth.to_dict(),
            "clamped_fraction": self.clamped_fraction,
        }
