"""DataFlash logs written with pymavlink's own writer code (``DFFormat`` for the
format letters, ``DFReader_binary.make_format_msgbuf`` / ``make_msgbuf`` for the bytes:
``A3 95 <type>`` then the packed fields, per ArduPilot's DataFlash layout), not
with gyrotherm's reader. Builds ``tests/data/ardupilot_two_imus.bin`` and the
legacy/malformed variants.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace

from pymavlink.DFReader import DFFormat, DFReader_binary

FMT = DFFormat(0x80, "FMT", 89, "BBnNZ", "Type,Length,Name,Format,Columns")
# ArduPilot AP_InertialSensor (4.x): IMU, "QBffffffIIfBBHH"
IMU = DFFormat(0x81, "IMU", 0, "QBffffffIIfBBHH",
               "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz")
GYR = DFFormat(0x82, "GYR", 0, "QBQfff", "TimeUS,I,SampleUS,GyrX,GyrY,GyrZ")
# ArduPilot 3.x: one message per instance, temperature in Temp
LEGACY = {name: DFFormat(0x83 + k, name, 0, "QffffffIIfBB",
                         "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,ErrG,ErrA,Temp,GyHlt,AcHlt")
          for k, name in enumerate(("IMU", "IMU2"))}
NO_TEMP = DFFormat(0x81, "IMU", 0, "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")

# (TimeUS, I, GyrX, GyrY, GyrZ rad/s, AccX, AccY, AccZ m/s², T °C), in log order
SAMPLES = [
    (5_000_000, 0, 0.01, 0.0, -0.5, 0.0, 0.0, -9.81, 35.0),
    (5_000_100, 1, math.pi, 0.0, 0.0, 0.1, 0.2, -9.7, 50.5),
    (5_002_500, 0, 0.02, 0.0, -0.5, 0.0, 0.0, -9.81, 35.125),
    (5_002_600, 1, math.pi, 0.0, 0.0, 0.1, 0.2, -9.7, 50.75),
    (5_002_500, 0, 0.99, 0.99, 0.99, 0.0, 0.0, -9.81, 99.0),  # repeated TimeUS: dropped
    (5_005_000, 0, 0.03, 0.0, -0.5, 0.0, 0.0, -9.81, 35.25),
]


def log(formats: Sequence[DFFormat], messages: Sequence[tuple[DFFormat, Sequence[object]]]
        ) -> bytes:
    w = SimpleNamespace(formats={0x80: FMT})  # the state make_format_msgbuf reads
    out = DFReader_binary.make_format_msgbuf(w, FMT)
    for f in formats:
        out += DFReader_binary.make_format_msgbuf(w, f)
    for f, values in messages:
        out += DFReader_binary.make_msgbuf(w, f, list(values))
    return bytes(out)


def two_imus() -> bytes:
    """IMU instances 0 and 1 interleaved, and GYR messages (no temperature: ignored)."""
    msgs: list[tuple[DFFormat, Sequence[object]]] = []
    for t, i, gx, gy, gz, ax, ay, az, temp in SAMPLES:
        msgs.append((IMU, [t, i, gx, gy, gz, ax, ay, az, 0, 0, temp, 1, 1, 400, 400]))
        msgs.append((GYR, [t, i, t - 50, gx, gy, gz]))
    return log([IMU, GYR], msgs)


def legacy() -> bytes:
    """ArduPilot 3.x style: IMU and IMU2 messages, Temp column."""
    msgs: list[tuple[DFFormat, Sequence[object]]] = []
    for t, i, gx, gy, gz, ax, ay, az, temp in SAMPLES[:4]:
        msgs.append((LEGACY[("IMU", "IMU2")[i]], [t, gx, gy, gz, ax, ay, az, 0, 0, temp, 1, 1]))
    return log(list(LEGACY.values()), msgs)


def no_temperature() -> bytes:
    msgs = [(NO_TEMP, [t, i, gx, gy, gz, ax, ay, az])
            for t, i, gx, gy, gz, ax, ay, az, _ in SAMPLES[:2]]
    return log([NO_TEMP], msgs)


def no_imu() -> bytes:
    return log([GYR], [(GYR, [t, i, t, gx, gy, gz]) for t, i, gx, gy, gz, *_ in SAMPLES])


if __name__ == "__main__":  # regenerate the committed fixture
    (Path(__file__).parent / "data" / "ardupilot_two_imus.bin").write_bytes(two_imus())
