"""Vectorised CAN payload packing: all rows of one DBC message at once, with numpy.

Payloads are packed from the DBC's own signal definitions exactly as
:class:`~gyrotherm.codecs.FrameEncoder` packs them (raw = round half to even of
``(value − offset)/scale``, clamped; two's complement; little-endian word
``raw << start`` and big-endian word as in ``_canmap``; unmapped signals 0;
rolling counter; CRC over every other byte). The first and last frame of each
message are also encoded by the ``FrameEncoder`` itself: they must match (else
``RuntimeError``), and the encoder's rolling counters continue after the run.
Messages with float signals or more than 8 bytes use the encoder row by row.
"""

from __future__ import annotations

from collections.abc import Callable

import can
import numpy as np

from gyrotherm.codecs._canmap import Field, MessagePlan


def _raw_values(values: np.ndarray, f: Field) -> tuple[np.ndarray, np.ndarray]:
    """(raw values as ``FrameEncoder`` rounds them, rows it would clamp); NaN rows are kept."""
    with np.errstate(invalid="ignore", over="ignore"):
        raw = (values - f.offset) / f.scale
        if not f.is_float:
            raw = np.where(np.isfinite(raw), np.round(raw), raw)
        outside = ~((raw >= f.raw_min) & (raw <= f.raw_max)) & ~np.isnan(raw)
    return raw, outside


def _vectorisable(plan: MessagePlan, given: int) -> bool:
    """Integer signals of at most 62 bits in a classic frame, unsent values (status) may be 0."""
    fields = [*plan.values, *([plan.counter] if plan.counter is not None else [])]
    return (
        plan.compiled
        and plan.length <= 8
        and all(f.mask.bit_length() <= 62 for f in fields)
        and all(f.raw_min <= 0 <= f.raw_max for f in plan.values[given:])
    )


def _pack(plan: MessagePlan, raws: list[np.ndarray], counter_start: int) -> list[bytes]:
    """Payloads as ``FrameEncoder(saturate=True)`` builds them, one per row (see ``_canmap``).

    ``raws`` holds the first ``len(raws)`` value fields (rounded, unclamped);
    further value fields (status) are sent as raw 0, the counter runs from
    ``counter_start``, the CRC covers every other byte.
    """
    n, length = len(raws[0]), plan.length
    words = {False: np.zeros(n, np.uint64), True: np.zeros(n, np.uint64)}  # by big_endian
    columns: list[tuple[Field, np.ndarray]] = list(zip(plan.values, raws, strict=False))
    if plan.counter is not None:
        counters = (counter_start + np.arange(n, dtype=np.int64)) % plan.counter.span
        columns.append((plan.counter, counters))
    for f, raw in columns:
        clamped = np.clip(raw, f.raw_min, f.raw_max).astype(np.int64)
        words[f.big_endian] |= (clamped & f.mask).astype(np.uint64) << np.uint64(f.shift)
    little = words[False].astype("<u8").view(np.uint8).reshape(n, 8)[:, :length]
    big = words[True].astype(">u8").view(np.uint8).reshape(n, 8)[:, 8 - length :]
    data = little | big
    if plan.crc is not None and plan.crc_field is not None:
        table = np.array(plan.crc.table, dtype=np.uint8)
        r = np.full(n, plan.crc.init, dtype=np.uint8)
        crc_at = plan.crc_field.byte_index
        for j in range(length):
            if j != crc_at:
                r = table[r ^ data[:, j]]
        data[:, crc_at] = r ^ np.uint8(plan.crc.xorout)
    blob = data.tobytes()
    return [blob[i * length : (i + 1) * length] for i in range(n)]


def _encode_rows(
    plan: MessagePlan,
    columns: list[np.ndarray],
    one: Callable[[int, int | None], can.Message],
) -> tuple[list[bytes], list[bool]]:
    """(payload, saturated?) per row; ``one(row, counter)`` encodes a row with the encoder.

    The first and the last row also go through ``one`` (so the encoder's rolling
    counter continues past this run) and must equal the vectorised payloads.
    """
    n = len(columns[0])
    raws, saturated = [], np.zeros(n, dtype=bool)
    for f, values in zip(plan.values, columns, strict=False):
        raw, outside = _raw_values(values, f)
        raws.append(raw)
        saturated |= outside
    flags: list[bool] = saturated.tolist()
    nan_rows = np.flatnonzero(np.any([np.isnan(r) for r in raws], axis=0))
    if len(nan_rows):
        one(int(nan_rows[0]), None)  # raises the encoder's DecodeError for NaN
    if not n or not _vectorisable(plan, len(columns)):
        return [bytes(one(i, None).data) for i in range(n)], flags
    first = bytes(one(0, None).data)
    start, ctr = 0, plan.counter
    if ctr is not None:
        word = int.from_bytes(first, "big" if ctr.big_endian else "little")
        start = (word >> ctr.shift) & ctr.mask
    payloads = _pack(plan, raws, start)
    last = payloads[-1]
    if n > 1:
        last = bytes(one(n - 1, None if ctr is None else (start + n - 1) % ctr.span).data)
    if (first, last) != (payloads[0], payloads[-1]):
        raise RuntimeError(f"message {plan.name!r}: vectorised payloads differ from FrameEncoder")
    return payloads, flags
