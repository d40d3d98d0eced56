"""Codecs: run files (CSV version 1), CAN frames (DBC via cantools), candump logs,
and the msgpack wire payloads published on Zenoh."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gyrotherm._lazy import lazy_names
from gyrotherm.codecs._can import (
    DecodeResult,
    DecoderStats,
    FrameDecoder,
    RateSample,
    Rejection,
    RejectReason,
    TemperatureSample,
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
from gyrotherm.codecs._wire import (
    SCHEMA_VERSION,
    CalibrationInfo,
    HealthMessage,
    MessageKind,
    RateMessage,
    StateMessage,
    StatusFlags,
    encode_calibration_info,
    encode_health,
    encode_rate,
    encode_state,
)

if TYPE_CHECKING:  # offline (run files, candump logs) and client side (decoding): lazy, see _LAZY
    from gyrotherm.codecs._candump import (
        format_candump_line,
        iter_candump,
        parse_candump_line,
        read_candump,
        write_candump,
    )
    from gyrotherm.codecs._candump_run import is_candump_log, run_from_candump
    from gyrotherm.codecs._runfile import (
        AXES,
        RUN_FILE_VERSION,
        Run,
        format_run,
        parse_run,
        read_run,
        write_run,
    )
    from gyrotherm.codecs._wire_decode import (
        decode_calibration_info,
        decode_health,
        decode_message,
        decode_rate,
        decode_state,
    )

_LAZY = {
    "format_candump_line": "gyrotherm.codecs._candump",
    "iter_candump": "gyrotherm.codecs._candump",
    "parse_candump_line": "gyrotherm.codecs._candump",
    "read_candump": "gyrotherm.codecs._candump",
    "write_candump": "gyrotherm.codecs._candump",
    "is_candump_log": "gyrotherm.codecs._candump_run",
    "run_from_candump": "gyrotherm.codecs._candump_run",
    "AXES": "gyrotherm.codecs._runfile",
    "RUN_FILE_VERSION": "gyrotherm.codecs._runfile",
    "Run": "gyrotherm.codecs._runfile",
    "format_run": "gyrotherm.codecs._runfile",
    "parse_run": "gyrotherm.codecs._runfile",
    "read_run": "gyrotherm.codecs._runfile",
    "write_run": "gyrotherm.codecs._runfile",
    "decode_calibration_info": "gyrotherm.codecs._wire_decode",
    "decode_health": "gyrotherm.codecs._wire_decode",
    "decode_message": "gyrotherm.codecs._wire_decode",
    "decode_rate": "gyrotherm.codecs._wire_decode",
    "decode_state": "gyrotherm.codecs._wire_decode",
}

__all__ = [
    "AXES",
    "CRC8_AUTOSAR",
    "CRC8_SAE_J1850",
    "CRC_ALGORITHMS",
    "DEFAULT_DBC_PATH",
    "RUN_FILE_VERSION",
    "SCHEMA_VERSION",
    "CalibrationInfo",
    "Crc8",
    "DecodeResult",
    "DecoderStats",
    "FrameDecoder",
    "FrameEncoder",
    "HealthMessage",
    "MessageKind",
    "RateLike",
    "RateMessage",
    "RateSample",
    "RejectReason",
    "Rejection",
    "Run",
    "SignalMap",
    "StateMessage",
    "StatusFlags",
    "TemperatureLike",
    "TemperatureSample",
    "crc8_algorithm",
    "decode_calibration_info",
    "decode_health",
    "decode_message",
    "decode_rate",
    "decode_state",
    "encode_calibration_info",
    "encode_health",
    "encode_rate",
    "encode_state",
    "format_candump_line",
    "format_run",
    "is_candump_log",
    "iter_candump",
    "parse_candump_line",
    "parse_run",
    "read_candump",
    "read_run",
    "run_from_candump",
    "write_candump",
    "write_run",
]


# the offline names, imported on first use (PEP 562): the daemon never loads them
__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
