"""Loading the daemon's calibration: the file (bounded, validated, plausible:
:func:`gyrotherm.compensation.read_calibration`) and its recorded device.

A calibration records the IMU it was fitted for in ``provenance.device_id`` (``fit``
writes it from the log: a PX4 ``device_id``, an ArduPilot instance, a CAN id). With
``device_id`` in gyrotherm.toml the daemon compares the two at start and on every
reload; ``device_mismatch`` (default ``"refuse"``) says what a mismatch does:

* ``"refuse"``: a CalibrationError naming the file and both ids (exit 2 at start;
  on SIGHUP the old calibration stays);
* ``"warn"``: one warning in the journal, the calibration is used.

A calibration that records no device is used, with one info line saying so.
Without ``device_id`` in the config nothing is compared.
"""

from __future__ import annotations

import logging
from pathlib import Path

from gyrotherm._errors import CalibrationError
from gyrotherm.compensation import Calibration, read_calibration

log = logging.getLogger("gyrotherm.daemon")

MISMATCH_POLICIES = ("refuse", "warn")


def load_daemon_calibration(path: Path, *, device_id: str | None,
                            device_mismatch: str = "refuse") -> tuple[Calibration, str]:
    """The calibration in ``path`` and its id, with the device check of the module
    docstring; CalibrationError names the file and the problem."""
    cal, cid = read_calibration(path)
    if device_id is None:
        return cal, cid
    recorded = cal.provenance.get("device_id")
    if recorded is None or recorded == "":
        log.info("%s records no device: cannot check it against device_id = %r", path,
                 device_id)
    elif str(recorded) != device_id:
        msg = (f"{path}: field 'provenance.device_id' = {str(recorded)!r} is not this "
               f"sensor's device_id = {device_id!r} (gyrotherm.toml): a calibration of "
               "another IMU")
        if device_mismatch == "refuse":
            raise CalibrationError(msg + "; refused (device_mismatch = \"refuse\")")
        log.warning("%s; used anyway (device_mismatch = \"warn\")", msg)
    return cal, cid
