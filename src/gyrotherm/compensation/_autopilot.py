"""The autopilots' own gyro temperature compensation: a cubic in T, fitted and written
as PX4 and ArduPilot parameters.

Both autopilots correct the gyro with a ΔT-free cubic in the sensor's temperature
reading T (°C), in rad/s, clamped to the calibrated range:

* **PX4** (``src/modules/temperature_compensation/TemperatureCompensation.cpp``,
  ``calc_thermal_offsets_3D``; parameters in ``temp_comp_params_gyro*.c``)::

      Δt = clamp(T, TC_Gi_TMIN, TC_Gi_TMAX) − TC_Gi_TREF
      offset_j = X0_j + X1_j·Δt + X2_j·Δt² + X3_j·Δt³       (rad/s, j = 0, 1, 2 = x, y, z)

  applied as ``corrected = data − thermal_offset − offset``
  (``src/lib/sensor_calibration/Gyroscope.hpp``, ``Correct``). PX4's fitting script
  (``Tools/process_sensor_caldata.py``) sets TMIN/TMAX to the logged extremes and
  ``TREF = 0.5·(TMIN + TMAX)``; parameter names ``TC_G<i>_X<k>_<j>``, ``TC_G<i>_ID``
  (the gyro's device id), ``TC_G<i>_TREF/TMIN/TMAX`` and ``TC_G_ENABLE``.
* **ArduPilot** (``libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp``,
  ``correct_sensor`` and ``polynomial_eval``)::

      T' = clamp(T, TMIN, TMAX),  Tc' = clamp(T_cal, TMIN, TMAX)
      p(u) = (c1·u + c2·u² + c3·u³)·1e-6                     (rad/s, no constant term)
      corrected = data − p(T' − 35) + p(Tc' − 35) − gyro_offset

  with a *fixed* reference ``TEMP_REFERENCE = 35 °C`` (the mid-point 0.5·(TMIN+TMAX) is
  used only by the SITL simulator, ``sitl_apply_gyro``), ``SCALE_FACTOR = 1e6`` and
  T_cal = ``INS_GYRn_CALTEMP``, the temperature of the gyro offset calibration. The
  constant is left to that offset (``Tools/scripts/tempcal_IMU.py``: "we don't save the
  first term of the polynomial"). Parameters ``INS_TCAL<n>_ENABLE``, ``_TMIN``, ``_TMAX``,
  ``_GYR<k>_X/Y/Z`` (k = 1..3, n = IMU number from 1).

One cubic b(T) = Σ_k x_k·(T − T_ref)^k (rad/s) serves both: PX4 takes x_k as they are;
ArduPilot takes the same polynomial re-expanded about 35 °C,
c_k = Σ_{m≥k} x_m·C(m, k)·(35 − T_ref)^(m−k), k = 1..3, times 1e6.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from math import comb, isfinite

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError

FloatArray = NDArray[np.float64]
AXES = ("x", "y", "z")
ARDUPILOT_TREF_C = 35.0
"""``TEMP_REFERENCE`` in AP_InertialSensor_tempcal.cpp (and ``TEMP_REF`` in tempcal_IMU.py)."""
ARDUPILOT_SCALE = 1.0e6
"""``SCALE_FACTOR`` in AP_InertialSensor_tempcal.cpp: parameters are coefficients × 1e6."""
PX4_INT32, PX4_REAL32 = 6, 9
"""MAVLink ``MAV_PARAM_TYPE`` codes in a QGroundControl .params file."""


@dataclass(frozen=True)
class CubicT:
    """b_axis(T) = Σ_{k=0..3} x_k·(clamp(T, t_min_c, t_max_c) − t_ref_c)^k, in rad/s.

    ``coefficients_rad_s[axis]`` = (x0, x1, x2, x3), units rad/s/°C^k."""

    t_ref_c: float
    t_min_c: float
    t_max_c: float
    coefficients_rad_s: Mapping[str, tuple[float, float, float, float]]

    def __post_init__(self) -> None:
        if not (isfinite(self.t_min_c) and isfinite(self.t_max_c) and isfinite(self.t_ref_c)
                and self.t_min_c < self.t_max_c):
            raise CalibrationError(f"cubic in T: bad range [{self.t_min_c}, {self.t_max_c}] "
                                   f"°C or reference {self.t_ref_c} °C")

    def bias_rad_s(self, axis: str, temperature_c: FloatArray) -> FloatArray:
        u = np.clip(np.asarray(temperature_c, dtype=np.float64), self.t_min_c,
                    self.t_max_c) - self.t_ref_c
        x0, x1, x2, x3 = self.coefficients_rad_s[axis]
        return np.asarray(x0 + u * (x1 + u * (x2 + u * x3)), dtype=np.float64)

    def bias_dps(self, axis: str, temperature_c: FloatArray) -> FloatArray:
        return np.degrees(self.bias_rad_s(axis, temperature_c))

    def about(self, t_ref_c: float, axis: str) -> tuple[float, float, float, float]:
        """The same polynomial's coefficients in powers of (T − ``t_ref_c``)."""
        x = self.coefficients_rad_s[axis]
        shift = t_ref_c - self.t_ref_c
        return tuple(  # type: ignore[return-value]
            sum(x[m] * comb(m, k) * shift ** (m - k) for m in range(k, 4)) for k in range(4))


def fit_cubic_t(
    temperature_c: Sequence[FloatArray], rates_dps: Sequence[Mapping[str, FloatArray]],
) -> CubicT:
    """Pooled least squares of the rates (°/s → rad/s) on a cubic in the raw temperature
    readings of every run given (one array per run; mask rows beforehand).

    T_min, T_max = the extremes of the readings, T_ref = (T_min + T_max)/2 (PX4's
    process_sensor_caldata.py). Solved in u = (T − T_ref)/h, h = (T_max − T_min)/2, for
    conditioning, then x_k = a_k/h^k."""
    if not temperature_c:
        raise CalibrationError("no runs to fit the cubic in T to")
    t = np.concatenate([np.asarray(v, dtype=np.float64) for v in temperature_c])
    lo, hi = float(t.min()), float(t.max())
    if not hi - lo >= 1.0:
        raise CalibrationError(f"the temperature spans only [{lo:g}, {hi:g}] °C: a cubic in T "
                               "needs a heating run (≥ 1 °C)")
    t_ref, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    u = (t - t_ref) / h
    design = np.column_stack([u**k for k in range(4)])
    axes = [a for a in AXES if all(a in r for r in rates_dps)]
    if not axes:
        raise CalibrationError("the runs share no rate axis")
    coefficients = {}
    for axis in axes:
        y = np.radians(np.concatenate([np.asarray(r[axis], np.float64) for r in rates_dps]))
        a, *_ = np.linalg.lstsq(design, y, rcond=None)
        x0, x1, x2, x3 = (float(a[k]) / h**k for k in range(4))
        coefficients[axis] = (x0, x1, x2, x3)
    return CubicT(t_ref, lo, hi, coefficients)


def px4_params(cubic: CubicT, *, instance: int, device_id: int) -> list[tuple[str, float, int]]:
    """(name, value, MAVLink type) of PX4's gyro thermal compensation for one gyro."""
    if not 0 <= instance <= 3:
        raise CalibrationError(f"PX4 has thermal parameters for gyros 0..3, not {instance}")
    if not 0 < device_id < 2**32:
        raise CalibrationError(f"PX4 device id {device_id} is not a 32-bit sensor id > 0")
    i = instance
    signed_id = device_id - 2**32 if device_id >= 2**31 else device_id  # stored as INT32
    out: list[tuple[str, float, int]] = [("TC_G_ENABLE", 1, PX4_INT32),
                                         (f"TC_G{i}_ID", signed_id, PX4_INT32),
                                         (f"TC_G{i}_TREF", cubic.t_ref_c, PX4_REAL32),
                                         (f"TC_G{i}_TMIN", cubic.t_min_c, PX4_REAL32),
                                         (f"TC_G{i}_TMAX", cubic.t_max_c, PX4_REAL32)]
    for k in range(4):
        for j, axis in enumerate(AXES):
            x = cubic.coefficients_rad_s.get(axis, (0.0, 0.0, 0.0, 0.0))
            out.append((f"TC_G{i}_X{k}_{j}", x[k], PX4_REAL32))
    return out


def px4_params_file(params: Sequence[tuple[str, float, int]], *, vehicle_id: int = 1,
                    component_id: int = 1) -> str:
    """QGroundControl .params text, tab-separated ``vehicle component name value type``
    (the layout process_sensor_caldata.py writes)."""
    lines = ["# Sensor thermal compensation parameters (gyrotherm export)", "#",
             "# Vehicle-Id Component-Id Name Value Type"]
    for name, value, kind in params:
        text = str(int(value)) if kind == PX4_INT32 else repr(float(value))
        lines.append(f"{vehicle_id}\t{component_id}\t{name}\t{text}\t{kind}")
    return "\n".join(lines) + "\n"


def ardupilot_params(cubic: CubicT, *, imu: int) -> list[tuple[str, float]]:
    """(name, value) of ArduPilot's INS_TCAL<imu> for the gyro (imu numbered from 1)."""
    if not 1 <= imu <= 3:
        raise CalibrationError(f"ArduPilot has INS_TCAL1..3, not INS_TCAL{imu}")
    p = f"INS_TCAL{imu}_"
    out: list[tuple[str, float]] = [(p + "ENABLE", 1), (p + "TMIN", cubic.t_min_c),
                                    (p + "TMAX", cubic.t_max_c)]
    about = {a: cubic.about(ARDUPILOT_TREF_C, a) for a in cubic.coefficients_rad_s}
    for k in range(1, 4):
        for axis in AXES:
            c = about.get(axis, (0.0, 0.0, 0.0, 0.0))[k]
            out.append((f"{p}GYR{k}_{axis.upper()}", c * ARDUPILOT_SCALE))
    return out


def ardupilot_params_file(params: Sequence[tuple[str, float]]) -> str:
    """Mission Planner / MAVProxy .param text: ``NAME,value`` per line."""
    lines = [f"{name},{int(v) if name.endswith('_ENABLE') else repr(float(v))}"
             for name, v in params]
    return "\n".join(lines) + "\n"
