"""Decode the gyro's CAN frames into rate and temperature samples.

A :class:`FrameDecoder` is built once from a DBC file and a
:class:`~gyrotherm.codecs.SignalMap`; per frame it returns a
:class:`RateSample`, a :class:`TemperatureSample` or a :class:`Rejection`. It
never raises for a bad frame. Checks, in order (the first failing one rejects):

1. ``unknown_id``: the (id, standard/extended) pair is neither mapped message;
   ignored and counted.
2. ``wrong_length``: payload length differs from the DBC message length.
3. ``crc_mismatch``: the CRC byte differs from the mapped algorithm computed
   over all other payload bytes in order.
4. ``decode_error``: the payload cannot be decoded (not bytes, cantools error).
5. ``counter_jump``: counter != (last + 1) mod 2**bits, ``last`` being the
   counter of the previous frame *of the same message* that passed checks 1–4
   (the first frame after construction or :meth:`~FrameDecoder.reset` has no
   predecessor). A repeated counter is a jump too. Policy (keyword-only
   ``on_counter_jump``): ``"deliver"`` (default) counts the jump and still
   returns the sample, since its data passed the CRC; ``"reject"`` returns a
   rejection. Either way the counter state moves to the new value, so the
   following frame is in sequence again. A frame rejected by 1–4 does not
   touch the counter state: the frame after a CRC failure counts as a jump.
6. ``out_of_range``: a mapped value, status or counter is outside the DBC
   signal's ``[minimum, maximum]`` (checked on raw values, see ``_canmap``).
   In the shipped DBC the raw pattern 0x8000 is the "invalid" marker and lies
   outside the range, so it is rejected here.

The per-reason counts (:meth:`FrameDecoder.stats`) count events: a delivered
frame after a jump counts under ``counter_jump`` although it is not rejected.

Bits are extracted either by cantools (``engine="cantools"``) or by the
``"compiled"`` engine (default) that is derived from the DBC signal
definitions (see ``_canmap``); both give identical results. A message with a
float (IEEE) mapped signal always goes through cantools. Not thread-safe: use
one decoder per receiving thread.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from operator import index
from types import MappingProxyType
from typing import Any, Literal

from gyrotherm._errors import ConfigError
from gyrotherm.codecs._canmap import (
    DEFAULT_DBC_PATH,
    EXTENDED_KEY,
    Field,
    MessagePlan,
    SignalMap,
    resolve_layout,
)


class RejectReason(StrEnum):
    """Why a frame yielded no sample (values are the names used in stats and logs)."""

    WRONG_LENGTH = "wrong_length"
    CRC_MISMATCH = "crc_mismatch"
    COUNTER_JUMP = "counter_jump"
    OUT_OF_RANGE = "out_of_range"
    DECODE_ERROR = "decode_error"
    UNKNOWN_ID = "unknown_id"


@dataclass(frozen=True, slots=True)
class RateSample:
    """Angular rate of the three axes in °/s at ``time_s`` (the frame timestamp, s)."""

    time_s: float
    rate_x_dps: float
    rate_y_dps: float
    rate_z_dps: float
    counter: int | None = None


@dataclass(frozen=True, slots=True)
class TemperatureSample:
    """Internal temperature in °C at ``time_s``; ``status`` is the raw status signal."""

    time_s: float
    temperature_c: float
    status: int | None = None
    counter: int | None = None


@dataclass(frozen=True, slots=True)
class Rejection:
    """A frame that yielded no sample: the reason and a message naming signal and value."""

    time_s: float
    arbitration_id: int
    reason: RejectReason
    detail: str
    message: str | None = None
    """DBC message name, ``None`` for ``unknown_id``."""


DecodeResult = RateSample | TemperatureSample | Rejection


@dataclass(frozen=True)
class DecoderStats:
    """Snapshot of a decoder's counts; ``events`` holds every reason (zeros included)."""

    frames: int
    rate_samples: int
    temperature_samples: int
    events: Mapping[RejectReason, int]


@dataclass(slots=True)
class _Fast:
    """Everything the hot path needs for one message, flattened for speed."""

    plan: MessagePlan
    is_rate: bool
    compiled: bool
    need_be: bool
    specs: tuple[tuple[bool, int, int, int, int], ...]
    """Per field (values, then counter): big-endian?, shift, mask, sign bit, 2**bits."""
    names: tuple[str, ...]
    limits: tuple[tuple[float, float], ...]
    fields: tuple[Field, ...]
    length: int
    crc_index: int
    """Byte index of the CRC, -1 when the message has none."""
    crc_table: tuple[int, ...]
    crc_init: int
    crc_xorout: int
    counter_span: int
    """0 when the message has no counter."""

    @classmethod
    def of(cls, plan: MessagePlan, *, is_rate: bool, compiled: bool) -> _Fast:
        fs = (*plan.values, *([plan.counter] if plan.counter is not None else []))
        crc = plan.crc
        return cls(
            plan=plan,
            is_rate=is_rate,
            compiled=compiled and plan.compiled,
            need_be=any(f.big_endian for f in fs),
            specs=tuple((f.big_endian, f.shift, f.mask, f.sign_bit, f.span) for f in fs),
            names=tuple(f.name for f in fs),
            limits=tuple((f.raw_min, f.raw_max) for f in fs),
            fields=fs,
            length=plan.length,
            crc_index=plan.crc_field.byte_index if plan.crc_field is not None else -1,
            crc_table=crc.table if crc is not None else (),
            crc_init=crc.init if crc is not None else 0,
            crc_xorout=crc.xorout if crc is not None else 0,
            counter_span=plan.counter.span if plan.counter is not None else 0,
        )


class FrameDecoder:
    """Frames → samples for one DBC + :class:`SignalMap`; see the module docstring.

    ``dbc_path`` defaults to the shipped ``gyro.dbc`` and ``signal_map`` to
    :meth:`SignalMap.default`. A mismatch between them raises
    :class:`gyrotherm.ConfigError` naming the DBC file, message and signal.
    """

    def __init__(
        self,
        dbc_path: str | os.PathLike[str] = DEFAULT_DBC_PATH,
        signal_map: SignalMap | None = None,
        *,
        on_counter_jump: Literal["deliver", "reject"] = "deliver",
        engine: Literal["compiled", "cantools"] = "compiled",
    ) -> None:
        if on_counter_jump not in ("deliver", "reject"):
            raise ConfigError(
                f"on_counter_jump must be 'deliver' or 'reject', got {on_counter_jump!r}"
            )
        if engine not in ("compiled", "cantools"):
            raise ConfigError(f"engine must be 'compiled' or 'cantools', got {engine!r}")
        self.signal_map = signal_map if signal_map is not None else SignalMap.default()
        self.layout = resolve_layout(dbc_path, self.signal_map)
        self.dbc_path = self.layout.dbc_path
        self.engine = engine
        self._reject_jumps = on_counter_jump == "reject"
        rate, temp = self.layout.rate, self.layout.temperature
        compiled = engine == "compiled"
        self._fast: dict[int, _Fast] = {
            rate.key: _Fast.of(rate, is_rate=True, compiled=compiled),
            temp.key: _Fast.of(temp, is_rate=False, compiled=compiled),
        }
        self._last: dict[int, int] = {}
        self._counts: Counter[RejectReason] = Counter()
        self._frames = 0
        self._samples = [0, 0]

    def can_filters(self) -> list[dict[str, Any]]:
        """python-can ``Bus(can_filters=...)`` entries that pass exactly the mapped frames."""
        return [
            {
                "can_id": p.frame_id,
                "can_mask": 0x1FFFFFFF if p.is_extended_id else 0x7FF,
                "extended": p.is_extended_id,
            }
            for p in (self.layout.rate, self.layout.temperature)
        ]

    def temperature_range_c(self) -> tuple[float, float] | None:
        """The temperatures this layout can deliver, °C: the temperature signal's
        accepted raw range in physical units (the DBC's [minimum, maximum] where it
        has one); None when unbounded (a float signal without limits)."""
        f = self.layout.temperature.values[0]
        ends = sorted((f.raw_min * f.scale + f.offset, f.raw_max * f.scale + f.offset))
        return (ends[0], ends[1]) if all(math.isfinite(v) for v in ends) else None

    def reset(self) -> None:
        """Forget the counter state (e.g. after a bus reconnect); counts are kept."""
        self._last.clear()

    def stats(self) -> DecoderStats:
        """Counts since construction."""
        return DecoderStats(
            frames=self._frames,
            rate_samples=self._samples[0],
            temperature_samples=self._samples[1],
            events=MappingProxyType({r: self._counts[r] for r in RejectReason}),
        )

    def decode(self, msg: Any) -> DecodeResult:
        """Decode a python-can ``can.Message`` (uses its timestamp as ``time_s``)."""
        try:
            if msg.is_error_frame or msg.is_remote_frame:
                kind = "error" if msg.is_error_frame else "remote"
                self._frames += 1
                return self._reject(float(msg.timestamp), int(msg.arbitration_id),
                                    RejectReason.DECODE_ERROR, f"{kind} frame has no payload", None)
            return self.decode_raw(msg.arbitration_id, msg.data, msg.timestamp,
                                   is_extended_id=msg.is_extended_id)
        except (AttributeError, TypeError, ValueError) as exc:
            self._frames += 1
            return self._reject(0.0, -1, RejectReason.DECODE_ERROR,
                                f"not a CAN message: {exc}", None)

    def _reject(self, time_s: float, arbitration_id: int, reason: RejectReason, detail: str,
                plan: MessagePlan | None, *, count: bool = True) -> Rejection:
        if count:
            self._counts[reason] += 1
        name = plan.name if plan is not None else None
        prefix = f"{self.dbc_path.name}: {name}: " if name else ""
        return Rejection(time_s, arbitration_id, reason, prefix + detail, name)

    def decode_raw(
        self,
        arbitration_id: int,
        data: bytes | bytearray | memoryview,
        time_s: float,
        *,
        is_extended_id: bool = False,
    ) -> DecodeResult:
        """Decode one frame given as id, payload and timestamp (s); never raises."""
        self._frames += 1
        try:
            arbitration_id = index(arbitration_id)
        except TypeError:
            return self._reject(time_s, -1, RejectReason.DECODE_ERROR,
                                f"frame id {arbitration_id!r} is not an integer", None)
        key = arbitration_id + EXTENDED_KEY if is_extended_id else arbitration_id
        fast = self._fast.get(key)
        if fast is None:
            return self._reject(time_s, arbitration_id, RejectReason.UNKNOWN_ID,
                                f"frame id 0x{arbitration_id:X} is not mapped", None)
        plan = fast.plan
        try:
            payload = bytes(data)
        except (TypeError, ValueError) as exc:
            return self._reject(time_s, arbitration_id, RejectReason.DECODE_ERROR,
                                f"payload is not bytes: {exc}", plan)
        if len(payload) != fast.length:
            return self._reject(time_s, arbitration_id, RejectReason.WRONG_LENGTH,
                                f"payload is {len(payload)} bytes, expected {fast.length}", plan)
        crc_index = fast.crc_index
        if crc_index >= 0:
            table = fast.crc_table
            r = fast.crc_init
            for b in payload[:crc_index] + payload[crc_index + 1 :]:
                r = table[r ^ b]
            r ^= fast.crc_xorout
            if r != payload[crc_index]:
                return self._reject(time_s, arbitration_id, RejectReason.CRC_MISMATCH,
                                    _crc_detail(plan, payload[crc_index], r), plan)
        if fast.compiled:
            int_le = int.from_bytes(payload, "little")
            int_be = int.from_bytes(payload, "big") if fast.need_be else 0
            raws: list[float] = []
            for big, shift, mask, sign, span in fast.specs:
                bits = ((int_be if big else int_le) >> shift) & mask
                raws.append(bits - span if bits & sign else bits)
        else:
            try:
                decoded = plan.message.decode_simple(payload, decode_choices=False, scaling=False)
                raws = [decoded[n] for n in fast.names]
            except Exception as exc:  # cantools: DecodeError, ValueError, KeyError, ...
                return self._reject(time_s, arbitration_id, RejectReason.DECODE_ERROR,
                                    f"cantools cannot decode: {exc}", plan)
        counter: int | None = None
        span = fast.counter_span
        if span:
            counter = int(raws[-1])
            last = self._last.get(key)
            self._last[key] = counter
            if last is not None and counter != (last + 1) % span:
                self._counts[RejectReason.COUNTER_JUMP] += 1
                if self._reject_jumps:
                    return self._reject(
                        time_s, arbitration_id, RejectReason.COUNTER_JUMP,
                        f"signal {fast.names[-1]!r} is {counter}, expected {(last + 1) % span}",
                        plan, count=False)
        for i, (lo, hi) in enumerate(fast.limits):
            if not lo <= raws[i] <= hi:
                return self._reject(time_s, arbitration_id, RejectReason.OUT_OF_RANGE,
                                    _range_detail(fast.fields[i], raws[i]), plan)
        v = plan.values
        if fast.is_rate:
            self._samples[0] += 1
            return RateSample(time_s, float(raws[0] * v[0].scale + v[0].offset),
                              float(raws[1] * v[1].scale + v[1].offset),
                              float(raws[2] * v[2].scale + v[2].offset), counter)
        self._samples[1] += 1
        status = int(raws[1]) if len(v) > 1 else None
        return TemperatureSample(time_s, float(raws[0] * v[0].scale + v[0].offset), status, counter)


def _crc_detail(plan: MessagePlan, got: int, want: int) -> str:
    assert plan.crc is not None and plan.crc_field is not None
    return (f"signal {plan.crc_field.name!r} is 0x{got:02X}, {plan.crc.name} of the other "
            f"bytes is 0x{want:02X}")


def _range_detail(f: Field, raw: float) -> str:
    value = raw * f.scale + f.offset
    unit = f" {f.unit}" if f.unit else ""
    return (f"signal {f.name!r} is {value:g}{unit} (raw {raw}), outside "
            f"[{f.minimum}, {f.maximum}]{unit}")
