"""Boot-time zero: the gyro's switch-on offset, measured at rest after power-on.

A MEMS gyro's bias has a run-to-run part, the switch-on offset (turn-on bias
repeatability), that no model in T, ΔT or time can predict: it is drawn anew at
each power-on. A calibration's intercept carries the mean offset of its training
runs, which is an error of every later run (docs/findings.md §5). PX4 and
ArduPilot zero the gyro at rest at boot; gyrotherm does the same *after* the
thermal model, so the zero removes only what the model cannot know::

    z_a = mean over the window of (ω_a − b_a)            per axis a, °/s

where ω is the raw rate and b the calibration's bias on the same sample. From
the sample that closes an accepted window on, the bias removed is ``b + z``
(the wire's ``bias_dps`` includes z).

**Window.** It opens at the first usable sample at least ``settle_s`` after the
start (power-on, or the load of another calibration) and closes at the first
sample at least ``window_s`` after it opened. It is **accepted** when, on every
axis, the residual ω − b has a standard deviation ≤ ``max_std_dps``, the means
of the window's two halves (split at ``window_s``/2) differ by ≤
``max_step_dps``, and |z| ≤ ``max_offset_dps``; each half needs two samples.
Otherwise a new window opens at the closing sample. An unusable sample (a
non-finite residual; on the vehicle also a frame flagged stale, bias-invalid or
sensor-fault) discards the open window; the next usable sample opens a new one.
(A frame after a counter jump is used: a lost frame does not bias a mean at rest.)
No accepted window within ``deadline_s`` of the start (the first sample, usable
or not): the zero **failed**, z = 0 until the next start.

Limits: the gyro alone cannot tell a constant-rate rotation from an offset.
A steady turn slower than ``max_offset_dps`` during the window is taken for an
offset (as ArduPilot's boot calibration would): zero the gyro at rest.

**Trusted or not.** A zero started at a power-on is *trusted*: the vehicle is
powered on at rest (the operating contract). A zero the daemon has to start at
another moment (a restart that could not restore one, a calibration loaded where
there was none, a clock step) may run while the vehicle moves; it is started
untrusted, optionally with a ``reference`` (the previous offset). When accepted,
it is **unverified** unless it agrees with the reference within ``max_step_dps``
on every axis: the daemon then flags ``ZERO_UNVERIFIED`` until the next power-on.
A **failed** zero stays failed across restarts and reloads until a power-on.

**Time jumps.** A sample whose time is behind the previous one, or more than
:data:`REBASE_JUMP_S` ahead of it (a time base change of the stream), does not
count towards the deadline: the start moves with the jump and the open window is
discarded (no spurious ``FAILED``).

One implementation serves the daemon (:meth:`BootZero.push` per rate frame) and
offline evaluation (:func:`zero_series` loops over rows with the same object),
so both give the same z bit for bit on the same samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.codecs._wire import ZeroStatus

__all__ = ["BootZero", "ZeroConfig", "ZeroSeries", "ZeroStatus", "check_saved", "zero_series"]

FloatArray = NDArray[np.float64]
_AXES = ("x", "y", "z")
#: A step of a sample's time larger than this (or backwards) is a time jump, s.
REBASE_JUMP_S = 60.0


_LIMITS: dict[str, tuple[float, float]] = {
    "window_s": (1.0, 3600.0),
    "settle_s": (0.0, 3600.0),
    "max_std_dps": (1e-6, 100.0),
    "max_step_dps": (1e-6, 10.0),
    "max_offset_dps": (1e-6, 100.0),
    "deadline_s": (1.0, 86400.0),
}


@dataclass(frozen=True)
class ZeroConfig:
    """The boot-time zero's settings (module docstring); bounds in :data:`_LIMITS`."""

    window_s: float = 10.0
    """Length of the rest window averaged, s."""
    settle_s: float = 30.0
    """Wait after the start before the first window opens, s: past the estimator's
    warm-up (20 readings: ≈ 25 s for a sensor that refreshes every 1.28 s)."""
    max_std_dps: float = 0.5
    """Rest check: largest standard deviation of ω − b in the window, per axis, °/s."""
    max_step_dps: float = 0.05
    """Rest check: largest difference between the two half-window means, per axis, °/s."""
    max_offset_dps: float = 1.0
    """Largest |z| accepted, per axis, °/s (a larger one is motion, not an offset)."""
    deadline_s: float = 600.0
    """Give up this long after the start, s (then ``FAILED``, z = 0)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            lo, hi = _LIMITS[f.name]
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(f"zero.{f.name}: expected a number, got {v!r}")
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ConfigError(f"zero.{f.name} = {v!r} is outside [{lo:g}, {hi:g}]")
            object.__setattr__(self, f.name, float(v))
        if self.settle_s + self.window_s > self.deadline_s:
            raise ConfigError(f"zero.deadline_s = {self.deadline_s:g} s leaves no room for "
                              f"settle_s + window_s = {self.settle_s + self.window_s:g} s")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str = "zero") -> ZeroConfig:
        """From a mapping (a TOML table); unknown or invalid fields are a ConfigError."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {unknown}; known: {sorted(known)}")
        try:
            return cls(**data)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from exc

    def to_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class BootZero:
    """The zero's state machine for one sensor (three axes); see the module docstring."""

    def __init__(self, config: ZeroConfig) -> None:
        self.config = config
        self.status = ZeroStatus.OFF
        self.offset_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.start_s = math.nan  # NaN: the start is the next pushed sample
        self.done_s = math.nan  # sensor time of the sample that closed the accepted window
        self.windows_rejected = 0
        self.trusted = True  # started at a power-on (module docstring)
        self.unverified = False  # accepted, untrusted, not confirmed by the reference
        self._reference: tuple[float, float, float] | None = None
        self._last_s = math.nan  # time of the latest sample pushed or interrupted
        self._open_s = math.nan
        self._sums = [0.0] * 14  # per half h at 7·h: n, Σx, Σy, Σz, Σx², Σy², Σz²

    def start(self, time_s: float = math.nan, *, trusted: bool = True,
              reference: tuple[float, float, float] | None = None) -> None:
        """(Re)start: pending from ``time_s`` (s, sensor time; NaN: the next sample);
        ``trusted``: at a power-on; ``reference``: an offset the result should agree
        with (°/s, only for an untrusted start)."""
        self.status, self.offset_dps = ZeroStatus.PENDING, (0.0, 0.0, 0.0)
        self.start_s, self.done_s, self._open_s = time_s, math.nan, math.nan
        self.trusted, self.unverified, self._reference = trusted, False, reference
        self._last_s = math.nan

    def stop(self) -> None:
        """Off: nothing removed, nothing measured."""
        self.status, self.offset_dps = ZeroStatus.OFF, (0.0, 0.0, 0.0)
        self.start_s = self.done_s = self._open_s = math.nan
        self.unverified = False

    def discard_window(self) -> None:
        """Drop the open window (its samples' residuals are against another model)."""
        self._open_s = math.nan

    def fail(self) -> None:
        """Failed (z = 0) until the next :meth:`start`."""
        self.status, self.offset_dps, self._open_s = ZeroStatus.FAILED, (0.0, 0.0, 0.0), math.nan

    def restore(self, saved: Mapping[str, Any] | None, time_s: float, *,
                power_on_s: float, saved_time_s: float) -> str:
        """Continue after a restart (the gyro kept running) from :meth:`to_dict`'s output
        (checked by :func:`check_saved`), re-checked against this config's bounds: a
        zero that was done keeps its offset, a failed one stays failed, a pending one
        goes on from its start (its deadline too). None saved, ``off``, or a field out
        of bounds: it starts again at ``time_s`` (s) *untrusted*, the vehicle may be
        moving. Returns what was done, for the journal."""
        if saved is None or saved.get("status") in (None, "off"):
            self.start(time_s, trusted=False)
            return "none saved: measured again now (unverified when taken)"
        problem = _out_of_bounds(saved, self.config, power_on_s, saved_time_s)
        if problem:
            self.start(time_s, trusted=False)
            return f"saved zero dropped ({problem}): measured again now (unverified when taken)"
        status = saved["status"]
        if status == "failed":
            self.start(time_s)
            self.fail()
            return "failed before the restart: stays failed until the next power-on"
        if status == "pending":
            start = saved.get("start_s")
            self.start(power_on_s if start is None else float(start),
                       trusted=bool(saved.get("trusted", True)))
            return f"pending since t = {self.start_s!r} s: goes on"
        x, y, z = (float(v) for v in saved["offset_dps"])
        done = saved.get("done_s")
        self.status, self.offset_dps = ZeroStatus.DONE, (x, y, z)
        self.done_s, self._open_s = math.nan if done is None else float(done), math.nan
        self.unverified = bool(saved.get("unverified", False))
        return "done: " + ", ".join(f"{v:+.5f}" for v in self.offset_dps) + " °/s kept"

    def _rebase(self, time_s: float) -> None:
        """Move the start with a time jump (module docstring)."""
        last = self._last_s
        if not math.isnan(last) and not (last <= time_s <= last + REBASE_JUMP_S):
            self.start_s += time_s - last
            self._open_s = math.nan
        self._last_s = time_s

    def interrupt(self, time_s: float) -> bool:
        """An unusable sample at ``time_s`` (s): the open window is discarded. The
        deadline still runs (it counts from the first sample, usable or not); True when
        the zero failed here."""
        if self.status != ZeroStatus.PENDING:
            return False
        self._open_s = math.nan
        if math.isnan(self.start_s):
            self.start_s = time_s
        self._rebase(time_s)
        if time_s - self.start_s > self.config.deadline_s:
            self.status = ZeroStatus.FAILED
            return True
        return False

    def push(self, time_s: float, x: float, y: float, z: float) -> bool:
        """One sample's residual ω − b (°/s) at ``time_s`` (s); True when the status
        changed (accepted, or failed at the deadline): the caller's bias changes."""
        if self.status != ZeroStatus.PENDING:
            return False
        if math.isnan(self.start_s):
            self.start_s = time_s
        self._rebase(time_s)
        since = time_s - self.start_s
        c = self.config
        if since > c.deadline_s:
            self.status, self._open_s = ZeroStatus.FAILED, math.nan
            return True
        if since < c.settle_s:
            return False
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            self._open_s = math.nan
            return False
        if math.isnan(self._open_s):
            self._open(time_s)
        elif time_s - self._open_s >= c.window_s:
            if self._accept(time_s):
                return True
            self.windows_rejected += 1
            self._open(time_s)
        s = self._sums
        i = 0 if time_s - self._open_s < c.window_s / 2 else 7
        s[i] += 1.0
        s[i + 1] += x
        s[i + 2] += y
        s[i + 3] += z
        s[i + 4] += x * x
        s[i + 5] += y * y
        s[i + 6] += z * z
        return False

    def _open(self, time_s: float) -> None:
        self._open_s = time_s
        self._sums = [0.0] * 14

    def _accept(self, time_s: float) -> bool:
        s, c = self._sums, self.config
        n0, n1 = s[0], s[7]
        if n0 < 2 or n1 < 2:
            return False
        n = n0 + n1
        offset = []
        for k in range(3):
            mean = (s[1 + k] + s[8 + k]) / n
            var = max(0.0, (s[4 + k] + s[11 + k]) / n - mean * mean)
            step = abs(s[1 + k] / n0 - s[8 + k] / n1)
            if math.sqrt(var) > c.max_std_dps or step > c.max_step_dps \
                    or abs(mean) > c.max_offset_dps:
                return False
            offset.append(mean)
        self.status, self.done_s, self._open_s = ZeroStatus.DONE, time_s, math.nan
        self.offset_dps = (offset[0], offset[1], offset[2])
        ref = self._reference
        self.unverified = not self.trusted and (ref is None or any(
            abs(o - r) > c.max_step_dps for o, r in zip(self.offset_dps, ref, strict=True)))
        return True

    def to_dict(self) -> dict[str, Any]:
        """What a restarted daemon needs (``status``, ``offset_dps``, ``done_s``,
        ``start_s``, ``trusted``, ``unverified``)."""
        return {"status": self.status.name.lower(), "offset_dps": list(self.offset_dps),
                "done_s": None if math.isnan(self.done_s) else self.done_s,
                "start_s": None if math.isnan(self.start_s) else self.start_s,
                "trusted": self.trusted, "unverified": self.unverified}


def _out_of_bounds(saved: Mapping[str, Any], config: ZeroConfig, power_on_s: float,
                   time_s: float) -> str:
    """Why a saved zero cannot be taken back (empty: it can): its offset beyond this
    config's ``max_offset_dps``, or its times outside [power-on, latest saved step]."""
    for k, v in enumerate(saved["offset_dps"]):
        if abs(v) > config.max_offset_dps:
            return (f"offset_dps[{k}] = {v!r} °/s is beyond max_offset_dps = "
                    f"{config.max_offset_dps:g} °/s")
    for key in ("done_s", "start_s"):
        v = saved.get(key)
        if v is not None and not power_on_s <= v <= time_s:
            return (f"{key} = {v!r} s is outside the saved run [power-on {power_on_s!r} s, "
                    f"latest step {time_s!r} s]")
    return ""


def check_saved(z: Any, source: str) -> dict[str, Any]:
    """:meth:`BootZero.to_dict`'s output read back from ``source`` (a state file):
    the same mapping with floats, or CalibrationError naming the field and value."""
    where = f"{source}: field 'zero"
    if not isinstance(z, dict):
        raise CalibrationError(f"{where}': expected an object, got {z!r:.60}")
    if z.get("status") not in {s.name.lower() for s in ZeroStatus}:
        raise CalibrationError(f"{where}.status': expected off, pending, done or failed, "
                               f"got {z.get('status')!r:.60}")
    off = z.get("offset_dps")
    if (not isinstance(off, list) or len(off) != 3 or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in off)):
        raise CalibrationError(f"{where}.offset_dps': expected 3 finite numbers (°/s), "
                               f"got {off!r:.60}")
    times = {}
    for key in ("done_s", "start_s"):
        v = z.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                              or not math.isfinite(v)):
            raise CalibrationError(f"{where}.{key}': expected a finite number or null, "
                                   f"got {v!r:.60}")
        times[key] = None if v is None else float(v)
    flags = {}
    for key in ("trusted", "unverified"):
        v = z.get(key, key == "trusted")
        if not isinstance(v, bool):
            raise CalibrationError(f"{where}.{key}': expected true or false, got {v!r:.60}")
        flags[key] = v
    return {"status": z["status"], "offset_dps": [float(v) for v in off], **times, **flags}


@dataclass(frozen=True)
class ZeroSeries:
    """:func:`zero_series`' result: the zero removed on each row (°/s, per axis) and
    how the zero ended."""

    offset_dps: Mapping[str, FloatArray]
    status: ZeroStatus
    done_s: float
    windows_rejected: int


def zero_series(config: ZeroConfig, time_s: FloatArray,
                residual_dps: Mapping[str, FloatArray]) -> ZeroSeries:
    """The zero along a recorded run started at its first row (power-on), as the
    daemon measures it: ``residual_dps`` is ω − b per axis (°/s, a missing axis
    counts as 0); the result's offsets are 0 before the accepting row and z from
    it on. Rows are pushed one by one only until the zero is decided."""
    n = len(time_s)
    cols = [np.asarray(residual_dps[a], dtype=np.float64) if a in residual_dps
            else np.zeros(n) for a in _AXES]
    zero = BootZero(config)
    zero.start(float(time_s[0]) if n else math.nan)
    decided = n
    for i in range(n):
        if zero.push(float(time_s[i]), float(cols[0][i]), float(cols[1][i]), float(cols[2][i])):
            decided = i
            break
    out = {}
    for k, a in enumerate(_AXES):
        if a in residual_dps:
            v = np.zeros(n)
            v[decided:] = zero.offset_dps[k]
            out[a] = v
    return ZeroSeries(out, zero.status, zero.done_s, zero.windows_rejected)
