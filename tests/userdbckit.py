"""A gyro with its own CAN ids, names, scales and byte order (not the shipped gyro.dbc):
its DBC, a signal map in the daemon's ``[can.signals]`` form, and candump logs of
frames encoded by cantools' own encoder (the lines written here, not by gyrotherm)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cantools

USER_DBC = """VERSION ""

NS_ :

BS_:

BU_: Imu Host

BO_ 928 ImuAngularRate: 6 Imu
 SG_ WX : 7|16@0- (0.01,0) [-300|300] "deg/s" Host
 SG_ WY : 23|16@0- (0.01,0) [-300|300] "deg/s" Host
 SG_ WZ : 39|16@0- (0.01,0) [-300|300] "deg/s" Host

BO_ 2566844416 ImuDieTemp: 4 Imu
 SG_ DieTemp : 0|16@1+ (0.0078125,-40) [-40|125] "degC" Host
 SG_ Flags : 16|8@1+ (1,0) [0|255] "" Host
"""
SIGNALS_TOML = """# the daemon's [can.signals] form
[can]
interface = "socketcan"
channel = "can0"

[can.signals]
rate_message = "ImuAngularRate"
rate_x_signal = "WX"
rate_y_signal = "WY"
rate_z_signal = "WZ"
temperature_message = "ImuDieTemp"
temperature_signal = "DieTemp"
status_signal = "Flags"
"""
#: (time s, temperature °C) then (time s, rates °/s): values on the DBC grids.
TEMPS = [(0.50, 30.0), (1.50, 30.5078125)]
RATES = [(0.60, (0.25, -1.5, 2.0)), (1.00, (0.3, -1.49, 1.99)), (1.60, (0.26, -1.51, 2.01))]


def user_log(tmp_path: Path, temps: Sequence[tuple[float, float]] = TEMPS,
             rates: Sequence[tuple[float, tuple[float, float, float]]] = RATES,
             ) -> tuple[Path, Path, Path]:
    """Log, DBC and signal-map files of the user's gyro: ``temps`` (s, °C) and
    ``rates`` (s, (x, y, z) °/s) encoded by cantools, one candump line each."""
    dbc = tmp_path / "imu.dbc"
    dbc.write_text(USER_DBC, encoding="utf-8")
    db = cantools.database.load_file(str(dbc))
    rate, temp = db.get_message_by_name("ImuAngularRate"), db.get_message_by_name("ImuDieTemp")
    frames = [(t, temp.frame_id, True, temp.encode({"DieTemp": c, "Flags": 0}))
              for t, c in temps]
    frames += [(t, rate.frame_id, False, rate.encode({"WX": x, "WY": y, "WZ": z}))
               for t, (x, y, z) in rates]
    lines = [f"({t:.6f}) can0 {i:08X}#{d.hex().upper()}" if ext else
             f"({t:.6f}) can0 {i:03X}#{d.hex().upper()}" for t, i, ext, d in sorted(frames)]
    log = tmp_path / "imu.log"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    signals = tmp_path / "signals.toml"
    signals.write_text(SIGNALS_TOML, encoding="utf-8")
    return log, dbc, signals
