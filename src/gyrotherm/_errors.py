"""Exception hierarchy: one base, one subclass per layer.

Every error names what was wrong (file, line, field, frame, signal) and the
value that was rejected, after cantools' style. Lower-level exceptions are
chained with ``raise ... from`` so the original cause stays visible.
"""

from __future__ import annotations


class GyrothermError(Exception):
    """Base class of every error gyrotherm raises on purpose."""


class RunFileError(GyrothermError):
    """A run file (CSV version 1) is malformed: names file, line and problem."""


class DecodeError(GyrothermError):
    """A CAN frame or wire payload could not be decoded."""


class ConfigError(GyrothermError):
    """A configuration file or option is invalid: names the field and the limit."""


class CalibrationError(GyrothermError):
    """A calibration is malformed, partial, of the wrong version, or cannot be fitted."""


class PublishError(GyrothermError):
    """Publishing to Zenoh failed."""


class BusError(GyrothermError):
    """A CAN bus link failed at run time (handshake timeout, connection lost):
    names the interface, the channel and the peer."""
