"""Codecs: run files (CSV version 1); CAN frames and wire payloads."""

from gyrotherm.codecs._runfile import (
    AXES,
    RUN_FILE_VERSION,
    Run,
    format_run,
    parse_run,
    read_run,
    write_run,
)

__all__ = ["AXES", "RUN_FILE_VERSION", "Run", "format_run", "parse_run", "read_run", "write_run"]
