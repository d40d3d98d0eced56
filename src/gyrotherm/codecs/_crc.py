"""CRC-8 algorithms for CAN frame protection, identified by catalogue name.

A CRC-8 is fully specified by the Rocksoft/Williams parameters (the names follow
the CRC RevEng catalogue):

===================  ======  =====  ======  =====  ======  ===========
name                 poly    init   refin   refout xorout  check("123456789")
===================  ======  =====  ======  =====  ======  ===========
``CRC-8/SAE-J1850``  0x1D    0xFF   false   false  0xFF    0x4B
``CRC-8/AUTOSAR``    0x2F    0xFF   false   false  0xFF    0xDF
===================  ======  =====  ======  =====  ======  ===========

``CRC-8/SAE-J1850`` is AUTOSAR's ``Crc_CalculateCRC8`` and the gyrotherm default;
``CRC-8/AUTOSAR`` is AUTOSAR's ``Crc_CalculateCRC8H2F``. Both are MSB-first
(not reflected): register ``r = init``; for each byte ``b``: ``r ^= b``, then 8
times ``r = (r << 1) ^ poly if r & 0x80 else r << 1`` (kept to 8 bits); the
result is ``r ^ xorout``. The implementation is table driven (one lookup per
byte). ``"none"`` names the absence of a CRC (see :func:`crc8_algorithm`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from gyrotherm._errors import ConfigError

CRC_NONE = "none"


def _table(poly: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        r = byte
        for _ in range(8):
            r = ((r << 1) ^ poly) & 0xFF if r & 0x80 else (r << 1) & 0xFF
        table.append(r)
    return tuple(table)


@dataclass(frozen=True)
class Crc8:
    """One non-reflected CRC-8 algorithm (width 8, refin = refout = false)."""

    name: str
    poly: int
    init: int
    xorout: int
    check: int
    """Published CRC of the ASCII bytes ``b"123456789"``."""
    table: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "table", _table(self.poly))

    def compute(self, data: Iterable[int]) -> int:
        """CRC of ``data`` (bytes or any iterable of 0..255 ints), 0..255."""
        table = self.table
        r = self.init
        for b in data:
            r = table[r ^ b]
        return r ^ self.xorout


CRC8_SAE_J1850 = Crc8("CRC-8/SAE-J1850", poly=0x1D, init=0xFF, xorout=0xFF, check=0x4B)
CRC8_AUTOSAR = Crc8("CRC-8/AUTOSAR", poly=0x2F, init=0xFF, xorout=0xFF, check=0xDF)

_ALGORITHMS = {a.name.lower(): a for a in (CRC8_SAE_J1850, CRC8_AUTOSAR)}
CRC_ALGORITHMS: tuple[str, ...] = (CRC8_SAE_J1850.name, CRC8_AUTOSAR.name, CRC_NONE)
"""Every name :func:`crc8_algorithm` accepts (case-insensitive)."""


def crc8_algorithm(name: str) -> Crc8 | None:
    """The algorithm called ``name`` (case-insensitive), or ``None`` for ``"none"``.

    An unknown name raises :class:`gyrotherm.ConfigError` listing the known ones.
    """
    key = name.strip().lower()
    if key == CRC_NONE:
        return None
    try:
        return _ALGORITHMS[key]
    except KeyError:
        raise ConfigError(
            f"crc_algorithm: unknown CRC algorithm {name!r}; expected one of {list(CRC_ALGORITHMS)}"
        ) from None
