"""Codecs: run files (CSV version 1), CAN frames (DBC via cantools), candump logs,
and the msgpack wire payloads published on Zenoh."""

from gyrotherm.codecs._can import (
    DecodeResult,
    DecoderStats,
    FrameDecoder,
    RateSample,
    Rejection,
    RejectReason,
    TemperatureSample,
)
from gyrotherm.codecs._candump import (
    format_candump_line,
    iter_candump,
    parse_candump_line,
    read_candump,
    write_candump,
)
from gyrotherm.codecs._canenc import FrameEncoder, RateLike, TemperatureLike
from gyrotherm.codecs._canmap import DEFAULT_DBC_PATH, SignalMap
from gyrotherm.codecs._crc import (
    CRC8_AUTOSAR,
    CRC8_SAE_J1850,
    CRC_ALGORITHMS,
    Crc8,
    crc8_algorithm,
)
from gyrotherm.codecs._runfile import (
    AXES,
    RUN_FILE_VERSION,
    Run,
    format_run,
    parse_run,
    read_run,
    write_run,
)

__all__ = [
    "AXES",
    "CRC8_AUTOSAR",
    "CRC8_SAE_J1850",
    "CRC_ALGORITHMS",
    "DEFAULT_DBC_PATH",
    "RUN_FILE_VERSION",
    "Crc8",
    "DecodeResult",
    "DecoderStats",
    "FrameDecoder",
    "FrameEncoder",
    "RateLike",
    "RateSample",
    "RejectReason",
    "Rejection",
    "Run",
    "SignalMap",
    "TemperatureLike",
    "TemperatureSample",
    "crc8_algorithm",
    "format_candump_line",
    "format_run",
    "iter_candump",
    "parse_candump_line",
    "parse_run",
    "read_candump",
    "read_run",
    "write_candump",
    "write_run",
]
