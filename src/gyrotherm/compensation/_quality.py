"""Quality gates: is there enough in these runs to fit a calibration from?

``gyrotherm fit`` checks every device's runs (their rest rows) before it writes a
calibration. Each gate measures one thing and compares it with a named threshold:

=====================  ======================================  =================================
gate                   measured                                refused when
=====================  ======================================  =================================
``rows``               rest rows of the device, all runs       < :data:`MIN_REST_ROWS`
``sample-rate``        median rows per second of the runs      < :data:`MIN_SAMPLE_RATE_HZ`
``temperature-stuck``  distinct temperatures (rest rows)       < :data:`MIN_DISTINCT_TEMPERATURES`
``temperature-span``   max − min temperature (rest rows), °C   < :data:`MIN_TEMPERATURE_SPAN_C`
``rate-range``         largest \\|rate\\| of any row, °/s       > :data:`MAX_GYRO_RATE_DPS`
``conditioning``       condition number of the model's design  > :data:`MAX_DESIGN_CONDITION`
``validation``         runs left out one at a time             < 2 (a warning, never a refusal)
=====================  ======================================  =================================

``sample-rate-recommended`` warns (never refuses) below
:data:`RECOMMENDED_SAMPLE_RATE_HZ`, naming PX4's logger setting (its default profile
logs ``sensor_gyro`` at 1 Hz).

A failed gate is a refusal (``fit`` exits 2 naming the gate, the measured value and the
threshold) unless ``--force``, which writes the calibration anyway with the failures in
its provenance (``quality_warnings``). ``validation`` only warns: a single run (or
``--no-validation``) leaves the calibration unscored on data it did not see.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from gyrotherm.compensation._fit import RunFeatures, default_scaling
from gyrotherm.compensation._models import ModelSpec

MIN_REST_ROWS = 50
"""Fewer rows than this (at rest, over all runs of a device) fit noise, not a bias curve."""
MIN_SAMPLE_RATE_HZ = 0.5
"""Below this the log is not a gyro recording (PX4's default profile logs 1 Hz)."""
RECOMMENDED_SAMPLE_RATE_HZ = 10.0
"""Below this a warning (never a refusal): rest detection and ΔT need faster rows."""
MIN_DISTINCT_TEMPERATURES = 3
"""Fewer distinct readings: the sensor is stuck or not logged (ArduPilot ``Temp`` = 0)."""
MIN_TEMPERATURE_SPAN_C = 5.0
"""A bias-versus-temperature curve over less than this is an extrapolation everywhere."""
MAX_GYRO_RATE_DPS = 4000.0
"""Beyond any MEMS gyro's full scale (±2000 °/s, ±4000 °/s at most): a unit error."""
MAX_DESIGN_CONDITION = 1.0e6
"""Column-normalised design matrix: above this the coefficients are not identifiable
(e.g. ΔT never varies, so the ΔT terms duplicate the constant)."""
MIN_VALIDATION_RUNS = 2


@dataclass(frozen=True)
class Gate:
    """One check: its name, what was measured, the threshold and the verdict."""

    name: str
    measured: float | None
    threshold: float
    unit: str
    passed: bool
    refuses: bool
    detail: str

    def line(self) -> str:
        value = ("singular" if self.name == "conditioning" else "none") \
            if self.measured is None else f"{self.measured:.6g}"
        verdict = "ok" if self.passed else "refused" if self.refuses else "warning"
        unit = f" {self.unit}" if self.unit else ""
        return (f"{self.name}: {value}{unit} (threshold {self.threshold:g}{unit}) "
                f"{verdict}: {self.detail}")

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


_BLOCK_ROWS = 1 << 16
"""Rows of the design formed at a time (:func:`design_condition`)."""


def _rest_temperatures(runs: Sequence[RunFeatures]) -> tuple[int, int, float]:
    """Rest rows, distinct temperature readings and their span (°C) over the runs,
    run by run (no copy of every run's rows at once)."""
    n, distinct, lo, hi = 0, np.zeros(0), np.inf, -np.inf
    for r in runs:
        t = r.rows(r.temperature_c)
        if len(t):
            n += len(t)
            distinct = np.union1d(distinct, np.unique(t))
            lo, hi = min(lo, float(t.min())), max(hi, float(t.max()))
    return n, len(distinct), (hi - lo) if n else 0.0


def _sample_rate_hz(runs: Sequence[RunFeatures]) -> float | None:
    rates = [1.0 / float(np.median(np.diff(r.time_s))) for r in runs
             if len(r.time_s) > 1 and float(np.median(np.diff(r.time_s))) > 0]
    return float(np.median(rates)) if rates else None


def design_condition(runs: Sequence[RunFeatures], spec: ModelSpec) -> float:
    """Condition number of the (column-normalised) design matrix over the rest rows,
    from its Gram matrix accumulated run by run; ``inf`` when rank-deficient."""
    k = len(spec.terms)
    gram = np.zeros((k, k))
    scaling = default_scaling(runs)
    for r in runs:
        t, d = r.rows(r.temperature_c), r.rows(r.delta_t_c)
        for start in range(0, len(t), _BLOCK_ROWS):  # bounded memory on long logs
            a = spec.design(*scaling.centre(t[start:start + _BLOCK_ROWS],
                                            d[start:start + _BLOCK_ROWS]))
            gram += a.T @ a
    norms = np.sqrt(np.diag(gram))
    if not np.all(norms > 0):
        return float("inf")
    eig = np.linalg.eigvalsh(gram / np.outer(norms, norms))
    if eig[0] <= eig[-1] * np.finfo(np.float64).eps:
        return float("inf")
    return float(np.sqrt(eig[-1] / eig[0]))


def check(runs: Sequence[RunFeatures], spec: ModelSpec, *, validation: bool) -> list[Gate]:
    """Every gate of the module docstring on one device's runs, in the table's order
    (the later ones are skipped when there are no rest rows to measure)."""
    n, distinct, span = _rest_temperatures(runs)
    gates = [Gate("rows", n, MIN_REST_ROWS, "rows", n >= MIN_REST_ROWS, True,
                  "rows at rest over all runs of the device; log longer, or still, "
                  "or check rest detection (--rest)")]
    rate = _sample_rate_hz(runs)
    gates.append(Gate("sample-rate", rate, MIN_SAMPLE_RATE_HZ, "Hz",
                      rate is not None and rate >= MIN_SAMPLE_RATE_HZ, True,
                      "median rows per second; log the gyro faster (PX4: SDLOG_PROFILE "
                      "'thermal calibration' or 'sensor comparison')"))
    if rate is not None and rate >= MIN_SAMPLE_RATE_HZ:
        gates.append(Gate("sample-rate-recommended", rate, RECOMMENDED_SAMPLE_RATE_HZ, "Hz",
                          rate >= RECOMMENDED_SAMPLE_RATE_HZ, False,
                          "slow for rest detection and ΔT; PX4's default logger profile "
                          "logs sensor_gyro at 1 Hz: set SDLOG_PROFILE 'thermal "
                          "calibration' (or 'sensor comparison') and log again"))
    if n:
        gates.append(Gate("temperature-stuck", distinct, MIN_DISTINCT_TEMPERATURES,
                          "distinct readings", distinct >= MIN_DISTINCT_TEMPERATURES, True,
                          "the temperature never changes: the sensor is stuck or not "
                          "logged (e.g. ArduPilot Temp = 0, PX4 SITL 0 °C)"))
        gates.append(Gate("temperature-span", span, MIN_TEMPERATURE_SPAN_C, "°C",
                          span >= MIN_TEMPERATURE_SPAN_C, True,
                          "temperature range at rest; record a warm-up from cold "
                          "(or several logs at different temperatures)"))
        peak = max((float(np.max(np.abs(v))) for r in runs for v in r.rates_dps.values()
                    if len(v)), default=0.0)
        gates.append(Gate("rate-range", peak, MAX_GYRO_RATE_DPS, "°/s",
                          peak <= MAX_GYRO_RATE_DPS, True,
                          "largest |rate|; check the rate unit (--columns x=...:rad/s)"))
        cond = design_condition(runs, spec)
        gates.append(Gate("conditioning", cond if np.isfinite(cond) else None,
                          MAX_DESIGN_CONDITION, "", cond <= MAX_DESIGN_CONDITION, True,
                          f"model {spec.name!r} is not identifiable from these rows "
                          "(too little variation in T or ΔT); use a simpler --model (t2) "
                          "or runs covering more temperatures and heating rates"))
    n_runs = len(runs) if validation else 0
    gates.append(Gate("validation", n_runs, MIN_VALIDATION_RUNS, "runs",
                      n_runs >= MIN_VALIDATION_RUNS, False,
                      "runs scored leave-one-run-out; with one run (or --no-validation) "
                      "the calibration is not checked on data it did not see: score it "
                      "with `gyrotherm evaluate CAL OTHER_RUNS`"))
    return gates


__all__ = [
    "MAX_DESIGN_CONDITION",
    "MAX_GYRO_RATE_DPS",
    "MIN_DISTINCT_TEMPERATURES",
    "MIN_REST_ROWS",
    "MIN_SAMPLE_RATE_HZ",
    "MIN_TEMPERATURE_SPAN_C",
    "RECOMMENDED_SAMPLE_RATE_HZ",
    "Gate",
    "check",
    "design_condition",
]
