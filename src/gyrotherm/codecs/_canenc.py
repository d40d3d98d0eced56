"""Encode rate / temperature samples into CAN frames (used by the simulator).

A :class:`FrameEncoder` uses the same DBC + :class:`~gyrotherm.codecs.SignalMap`
as :class:`~gyrotherm.codecs.FrameDecoder`. Physical values become raw values as
``round((value - offset) / scale)`` (round half to even, as cantools); signals
of the message that are not mapped (reserved bits) are sent as raw 0; cantools
packs the bits; then the rolling counter (its own per message, starting at 0,
+1 modulo ``2**bits`` per frame) and the CRC (over every other byte, in order)
are filled in.

A value whose raw value falls outside the DBC signal's range (or the bit
width) raises :class:`gyrotherm.DecodeError` naming DBC file, message, signal,
limits and value, unless the keyword-only ``saturate=True`` clamps it to the
nearest limit. NaN always raises. A decoded frame therefore always lies within
half an LSB of the encoded value (or is the clamped limit).
"""

from __future__ import annotations

import math
import os
from typing import Any, Protocol

import can

from gyrotherm._errors import DecodeError
from gyrotherm.codecs._canmap import DEFAULT_DBC_PATH, Field, MessagePlan, SignalMap, resolve_layout


class RateLike(Protocol):
    """Anything with a timestamp (s) and three rates (°/s), e.g. a RateSample."""

    @property
    def time_s(self) -> float: ...
    @property
    def rate_x_dps(self) -> float: ...
    @property
    def rate_y_dps(self) -> float: ...
    @property
    def rate_z_dps(self) -> float: ...


class TemperatureLike(Protocol):
    """Anything with a timestamp (s) and a temperature (°C); ``status`` is read if present."""

    @property
    def time_s(self) -> float: ...
    @property
    def temperature_c(self) -> float: ...


class FrameEncoder:
    """Samples → ``can.Message`` for one DBC + :class:`SignalMap` (see the module docstring)."""

    def __init__(
        self,
        dbc_path: str | os.PathLike[str] = DEFAULT_DBC_PATH,
        signal_map: SignalMap | None = None,
    ) -> None:
        self.signal_map = signal_map if signal_map is not None else SignalMap.default()
        self.layout = resolve_layout(dbc_path, self.signal_map)
        self.dbc_path = self.layout.dbc_path
        self._next: dict[int, int] = {}

    def reset(self) -> None:
        """Restart every rolling counter at 0."""
        self._next.clear()

    def encode(self, sample: RateLike | TemperatureLike, *, saturate: bool = False) -> can.Message:
        """Encode a rate-like or temperature-like sample (chosen by its attributes)."""
        if hasattr(sample, "rate_x_dps"):
            return self.encode_rate(sample, saturate=saturate)  # type: ignore[arg-type]
        if hasattr(sample, "temperature_c"):
            return self.encode_temperature(sample, saturate=saturate)
        raise TypeError(f"cannot encode {type(sample).__name__}: no rate_x_dps or temperature_c")

    def encode_rate(
        self, sample: RateLike, *, saturate: bool = False, counter: int | None = None
    ) -> can.Message:
        """The rate frame for ``sample``; ``counter`` overrides the rolling counter."""
        plan = self.layout.rate
        values = (sample.rate_x_dps, sample.rate_y_dps, sample.rate_z_dps)
        return self._encode(plan, sample.time_s, values, saturate=saturate, counter=counter)

    def encode_temperature(
        self, sample: TemperatureLike, *, saturate: bool = False, counter: int | None = None
    ) -> can.Message:
        """The temperature frame for ``sample`` (status 0 if it has none)."""
        plan = self.layout.temperature
        values: tuple[Any, ...] = (sample.temperature_c,)
        if len(plan.values) > 1:
            status = getattr(sample, "status", None)
            values = (sample.temperature_c, 0 if status is None else status)
        return self._encode(plan, sample.time_s, values, saturate=saturate, counter=counter)

    def _where(self, plan: MessagePlan, f: Field) -> str:
        return f"{self.dbc_path}: message {plan.name!r} signal {f.name!r}"

    def _raw(self, plan: MessagePlan, f: Field, value: Any, *, saturate: bool) -> int | float:
        unit = f" {f.unit}" if f.unit else ""
        try:
            v = float(value)
        except (TypeError, ValueError) as exc:
            raise DecodeError(f"{self._where(plan, f)}: value {value!r} is not a number") from exc
        if math.isnan(v):
            raise DecodeError(f"{self._where(plan, f)}: value is NaN")
        raw: float = (v - f.offset) / f.scale
        if not f.is_float and math.isfinite(raw):
            raw = round(raw)
        if f.raw_min <= raw <= f.raw_max:
            return raw
        lo = f.raw_min * f.scale + f.offset
        hi = f.raw_max * f.scale + f.offset
        if saturate:
            return f.raw_min if raw < f.raw_min else f.raw_max
        raise DecodeError(
            f"{self._where(plan, f)}: value {v:g}{unit} is outside the encodable range "
            f"[{min(lo, hi):g}, {max(lo, hi):g}]{unit} (DBC [{f.minimum}, {f.maximum}]); "
            f"pass saturate=True to clamp"
        )

    def _encode(self, plan: MessagePlan, time_s: float, values: tuple[Any, ...], *,
                saturate: bool, counter: int | None) -> can.Message:
        n_physical = 3 if plan is self.layout.rate else 1  # status never saturates
        raws: dict[str, int | float] = {s.name: 0 for s in plan.message.signals}
        for i, (f, value) in enumerate(zip(plan.values, values, strict=True)):
            raws[f.name] = self._raw(plan, f, value, saturate=saturate and i < n_physical)
        if plan.counter is not None:
            c = self._next.get(plan.key, 0) if counter is None else counter
            if not 0 <= c < plan.counter.span:
                raise DecodeError(
                    f"{self._where(plan, plan.counter)}: counter {c} is outside "
                    f"[0, {plan.counter.span - 1}]"
                )
            raws[plan.counter.name] = c
            self._next[plan.key] = (c + 1) % plan.counter.span
        try:
            data = bytearray(
                plan.message.encode(raws, scaling=False, padding=False, strict=False)
            )
        except Exception as exc:  # cantools EncodeError and friends
            raise DecodeError(f"{self.dbc_path}: message {plan.name!r}: {exc}") from exc
        if plan.crc is not None and plan.crc_field is not None:
            data[plan.crc_field.byte_index] = plan.crc.compute(plan.covered(bytes(data)))
        return can.Message(
            timestamp=float(time_s),
            arbitration_id=plan.frame_id,
            is_extended_id=plan.is_extended_id,
            data=data,
            is_fd=plan.length > 8,
        )
