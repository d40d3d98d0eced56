"""Which DBC messages and signals carry the gyro's rate and temperature.

:class:`SignalMap` names them; :func:`resolve_layout` loads the DBC with
cantools, checks the names and pre-computes everything the hot decode path
needs, from the DBC's own signal definitions (start bit, length, byte order,
signedness, scale, offset, minimum, maximum). No frame id, bit position or
scale of the shipped ``gyro.dbc`` appears in code.

Bit extraction (the ``compiled`` engine) is generic: the payload of length
``L`` bytes is read once as an integer in both byte orders; a little-endian
(Intel) signal of length ``n`` starting at DBC bit ``s`` is
``(int_le >> s) & (2**n - 1)``; a big-endian (Motorola) signal whose MSB sits at
DBC (sawtooth) bit ``s`` is ``(int_be >> (8*L - (p + n))) & (2**n - 1)`` with
network bit ``p = 8*(s // 8) + 7 - s % 8``. Signed raw values are two's
complement. The physical value is ``raw * scale + offset`` as in cantools.

Range limits are applied to raw values: ``[minimum, maximum]`` from the DBC,
mapped to raw and rounded inward (ceil / floor), intersected with what the bit
width can hold. A DBC range of ``[0|0]`` means "none" (cantools stores ``None``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields
from pathlib import Path
from typing import Any

import cantools

from gyrotherm._errors import ConfigError
from gyrotherm.codecs._crc import CRC_NONE, Crc8, crc8_algorithm

DEFAULT_DBC_PATH = Path(__file__).with_name("gyro.dbc")
"""The shipped DBC: rate frame 0x120 ``GyroRate``, temperature frame 0x121 ``GyroTemperature``."""

EXTENDED_KEY = 1 << 31
"""Added to an extended (29-bit) frame id to form the lookup key, as DBC files do."""


_ID_FIELDS = ("rate_frame_id", "temperature_frame_id")


@dataclass(frozen=True)
class SignalMap:
    """Names of the DBC messages and signals that carry the gyro's data.

    The rate and temperature messages must be distinct. Counter and CRC
    signals are optional per message (``None``: not checked, not sent).
    ``crc_algorithm`` is a name from :data:`gyrotherm.codecs.CRC_ALGORITHMS`;
    it must be ``"none"`` exactly when neither message has a CRC signal.
    A CRC signal must be an unsigned byte on a byte boundary; the CRC covers
    every other payload byte, in order.
    """

    rate_message: str
    rate_x_signal: str
    rate_y_signal: str
    rate_z_signal: str
    temperature_message: str
    temperature_signal: str
    rate_counter_signal: str | None = None
    rate_crc_signal: str | None = None
    temperature_counter_signal: str | None = None
    temperature_crc_signal: str | None = None
    status_signal: str | None = None
    crc_algorithm: str = CRC_NONE
    rate_frame_id: int | None = None
    temperature_frame_id: int | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in _ID_FIELDS:
                if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                                          or not 0 <= value <= 0x1FFFFFFF):
                    raise ConfigError(f"signal map: {f.name} must be a CAN id in "
                                      f"[0, 0x1FFFFFFF] or None, got {value!r}")
                continue
            optional = f.default is None
            if not (isinstance(value, str) and value) and not (optional and value is None):
                raise ConfigError(
                    f"signal map: {f.name} must be a non-empty string"
                    f"{' or None' if optional else ''}, got {value!r}"
                )
        has_crc = self.rate_crc_signal is not None or self.temperature_crc_signal is not None
        is_none = crc8_algorithm(self.crc_algorithm) is None
        if has_crc and is_none:
            raise ConfigError(
                f"signal map: crc_algorithm is {self.crc_algorithm!r} but a CRC signal is mapped "
                f"(rate_crc_signal={self.rate_crc_signal!r}, "
                f"temperature_crc_signal={self.temperature_crc_signal!r})"
            )
        if not has_crc and not is_none:
            raise ConfigError(
                f"signal map: crc_algorithm is {self.crc_algorithm!r} but no CRC signal is mapped"
            )
        if self.rate_message == self.temperature_message:
            raise ConfigError(
                f"signal map: rate_message and temperature_message must differ, "
                f"both are {self.rate_message!r}"
            )

    @classmethod
    def default(cls) -> SignalMap:
        """The mapping of the shipped ``gyro.dbc`` (:data:`DEFAULT_DBC_PATH`)."""
        return cls(
            rate_message="GyroRate",
            rate_x_signal="RateX",
            rate_y_signal="RateY",
            rate_z_signal="RateZ",
            temperature_message="GyroTemperature",
            temperature_signal="Temperature",
            rate_counter_signal="RateCounter",
            rate_crc_signal="RateCrc",
            temperature_counter_signal="TempCounter",
            temperature_crc_signal="TempCrc",
            status_signal="Status",
            crc_algorithm="CRC-8/SAE-J1850",
        )

    @classmethod
    def from_dict(cls, values: Mapping[str, Any], *, source: str = "signal map") -> SignalMap:
        """Build from a config table (keys = field names); unknown keys raise ConfigError."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ConfigError(
                f"{source}: unknown key(s) {unknown}; expected some of {sorted(known)}"
            )
        required = [f.name for f in fields(cls)
                    if f.default is MISSING and f.default_factory is MISSING]  # fmt: skip
        missing = [name for name in required if name not in values]
        if missing:
            raise ConfigError(
                f"{source}: missing key(s) {missing}: a signal map names the rate message "
                "and its x, y, z signals and the temperature message and signal"
            )
        try:
            return cls(**values)
        except TypeError as exc:
            raise ConfigError(f"{source}: {exc}") from exc


@dataclass(frozen=True)
class Field:
    """One signal, pre-resolved for extraction and range checking (raw units)."""

    name: str
    big_endian: bool
    shift: int
    mask: int
    sign_bit: int
    """``2**(n-1)`` for a signed integer signal, else 0."""
    span: int
    """``2**n``."""
    is_float: bool
    scale: float
    offset: float
    raw_min: float
    raw_max: float
    minimum: float | None
    maximum: float | None
    unit: str
    byte_index: int
    """Byte holding the signal's first bit (meaningful for byte-aligned signals)."""


@dataclass(frozen=True)
class MessagePlan:
    """One mapped message: cantools object, lookup key, and its mapped fields."""

    name: str
    message: Any
    """The cantools ``Message``."""
    key: int
    frame_id: int
    is_extended_id: bool
    length: int
    values: tuple[Field, ...]
    """Rate: x, y, z. Temperature: temperature, then status if mapped."""
    counter: Field | None
    crc: Crc8 | None
    crc_field: Field | None
    compiled: bool
    """True when every mapped signal is an integer (the bit-extraction path applies)."""

    def covered(self, data: bytes) -> bytes:
        """The bytes the CRC covers: all but the CRC byte."""
        assert self.crc_field is not None
        i = self.crc_field.byte_index
        return data[:i] + data[i + 1 :]


@dataclass(frozen=True)
class Layout:
    dbc_path: Path
    rate: MessagePlan
    temperature: MessagePlan


def _field(dbc: Path, message: Any, signal_name: str, role: str) -> Field:
    where = f"{dbc}: message {message.name!r}"
    try:
        sig = message.get_signal_by_name(signal_name)
    except KeyError:
        names = ", ".join(s.name for s in message.signals)
        raise ConfigError(
            f"{where} has no signal {signal_name!r} (for {role}); its signals: {names}"
        ) from None
    if sig.multiplexer_ids is not None:
        raise ConfigError(f"{where} signal {signal_name!r} ({role}) is multiplexed; not supported")
    n, scale, offset = int(sig.length), sig.scale, sig.offset
    if scale == 0:
        raise ConfigError(f"{where} signal {signal_name!r} ({role}) has scale 0")
    length = int(message.length)
    if sig.byte_order == "little_endian":
        big, shift, first_bit = False, int(sig.start), int(sig.start)
    else:
        net = 8 * (sig.start // 8) + 7 - sig.start % 8
        big, shift, first_bit = True, 8 * length - (net + n), net
    if shift < 0 or shift + n > 8 * length:
        raise ConfigError(f"{where} signal {signal_name!r} ({role}) does not fit in {length} bytes")
    if sig.is_float:
        lo_bits, hi_bits = -math.inf, math.inf
    elif sig.is_signed:
        lo_bits, hi_bits = -(1 << (n - 1)), (1 << (n - 1)) - 1
    else:
        lo_bits, hi_bits = 0, (1 << n) - 1
    raw_lo: float = lo_bits
    raw_hi: float = hi_bits
    bounds = [None if v is None else (v - offset) / scale for v in (sig.minimum, sig.maximum)]
    lo_lim, hi_lim = bounds if scale > 0 else bounds[::-1]
    if lo_lim is not None:
        eps = 1e-9 * max(1.0, abs(lo_lim))
        raw_lo = max(raw_lo, lo_lim if sig.is_float else math.ceil(lo_lim - eps))
    if hi_lim is not None:
        eps = 1e-9 * max(1.0, abs(hi_lim))
        raw_hi = min(raw_hi, hi_lim if sig.is_float else math.floor(hi_lim + eps))
    return Field(
        name=sig.name,
        big_endian=big,
        shift=shift,
        mask=(1 << n) - 1,
        sign_bit=(1 << (n - 1)) if sig.is_signed and not sig.is_float else 0,
        span=1 << n,
        is_float=bool(sig.is_float),
        scale=scale,
        offset=offset,
        raw_min=raw_lo,
        raw_max=raw_hi,
        minimum=sig.minimum,
        maximum=sig.maximum,
        unit=sig.unit or "",
        byte_index=first_bit // 8,
    )


def _plain_unsigned(dbc: Path, message: Any, f: Field, role: str, *, bits: int | None) -> None:
    where = f"{dbc}: message {message.name!r} signal {f.name!r} ({role})"
    if f.is_float or f.sign_bit or f.scale != 1 or f.offset != 0:
        raise ConfigError(f"{where} must be an unsigned integer with scale 1 and offset 0")
    n = f.mask.bit_length()
    if bits is not None:
        if n != bits:
            raise ConfigError(f"{where} must be {bits} bits long, is {n}")
        if f.shift % 8:
            raise ConfigError(f"{where} must sit on a byte boundary")


def _plan(dbc: Path, db: Any, name: str, values: list[tuple[str, str]],
          counter: str | None, crc_name: str | None, crc: Crc8 | None,
          frame_id: int | None = None) -> MessagePlan:
    try:
        message = db.get_message_by_name(name)
    except KeyError:
        names = ", ".join(m.name for m in db.messages)
        raise ConfigError(f"{dbc}: no message {name!r}; its messages: {names}") from None
    if message.is_container:
        raise ConfigError(f"{dbc}: message {name!r} is a container message; not supported")
    value_fields = tuple(_field(dbc, message, sig, role) for sig, role in values)
    for f, (_, role) in zip(value_fields, values, strict=True):
        if role == "status":
            _plain_unsigned(dbc, message, f, role, bits=None)
    counter_field = None
    if counter is not None:
        counter_field = _field(dbc, message, counter, "counter")
        _plain_unsigned(dbc, message, counter_field, "counter", bits=None)
    crc_field = None
    if crc_name is not None:
        crc_field = _field(dbc, message, crc_name, "CRC")
        _plain_unsigned(dbc, message, crc_field, "CRC", bits=8)
    all_fields = [*value_fields, counter_field, crc_field]
    ext = bool(message.is_extended_frame)
    fid = int(message.frame_id) if frame_id is None else frame_id
    if not ext and fid > 0x7FF:
        raise ConfigError(f"{dbc}: message {name!r} is a standard (11-bit) frame: frame id "
                          f"override {fid:#x} is above 0x7ff")
    return MessagePlan(
        name=message.name,
        message=message,
        key=fid + (EXTENDED_KEY if ext else 0),
        frame_id=fid,
        is_extended_id=ext,
        length=int(message.length),
        values=value_fields,
        counter=counter_field,
        crc=crc if crc_field is not None else None,
        crc_field=crc_field,
        compiled=not any(f.is_float for f in all_fields if f is not None),
    )


def resolve_layout(dbc_path: str | os.PathLike[str], signal_map: SignalMap) -> Layout:
    """Load ``dbc_path`` and resolve ``signal_map`` against it (ConfigError on any mismatch)."""
    dbc = Path(dbc_path)
    try:
        db = cantools.database.load_file(str(dbc))
    except Exception as exc:  # cantools raises many types (OSError, ParseError, ...)
        raise ConfigError(f"{dbc}: cannot load CAN database: {exc}") from exc
    if not hasattr(db, "get_message_by_name"):
        raise ConfigError(f"{dbc}: not a CAN database")
    crc = crc8_algorithm(signal_map.crc_algorithm)
    m = signal_map
    rate = _plan(dbc, db, m.rate_message,
                 [(m.rate_x_signal, "rate x"), (m.rate_y_signal, "rate y"),
                  (m.rate_z_signal, "rate z")],
                 m.rate_counter_signal, m.rate_crc_signal, crc, m.rate_frame_id)
    temp_values = [(m.temperature_signal, "temperature")]
    if m.status_signal is not None:
        temp_values.append((m.status_signal, "status"))
    temperature = _plan(dbc, db, m.temperature_message, temp_values,
                        m.temperature_counter_signal, m.temperature_crc_signal, crc,
                        m.temperature_frame_id)
    if rate.key == temperature.key:
        raise ConfigError(f"{dbc}: messages {rate.name!r} and {temperature.name!r} share frame id")
    return Layout(dbc_path=dbc, rate=rate, temperature=temperature)
