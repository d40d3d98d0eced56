"""Test helper: a generated flight, written as a PX4 ULog (the published format, via
ulogkit's message builders) and an ArduPilot DataFlash log (pymavlink's own writer code,
via dataflashkit), so that rest detection's behaviour in flight is tested without the
real-log corpus.

The timeline (:data:`SCHEDULE`) holds what rest detection must get right: still
stretches on the ground, a hand-carried turn, armed rows sitting still (motors idling),
a flight turning at up to 180 °/s with a constant-rate yaw, a 20-s still stretch between
the landing and a 35-s logging gap, 15 s still after the gap before a turn (20 + 15 s of
rows, but 70 s from first to last: the gap once counted toward the 30-s minimum), and
still stretches after. Every value comes from a seeded generator: the truth per row
(turning, armed, logged in the gap) is known here, independently of gyrotherm.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import dataflashkit as dfk
import ulogkit as uk

RATE_HZ = 25.0
G_MPS2 = 9.80665
#: (start s, end s, what): "still", "turn" (hand-carried, disarmed), "idle" (armed,
#: still, motors idling), "fly" (armed, turning), "gap" (not logged).
SCHEDULE = (
    (0.0, 120.0, "still"), (120.0, 150.0, "turn"), (150.0, 200.0, "still"),
    (200.0, 260.0, "idle"), (260.0, 380.0, "fly"), (380.0, 400.0, "idle"),
    (400.0, 420.0, "still"), (420.0, 455.0, "gap"), (455.0, 470.0, "still"),
    (470.0, 480.0, "turn"), (480.0, 520.0, "still"), (520.0, 530.0, "turn"),
    (530.0, 600.0, "still"),
)
#: Stretches that are truly still, disarmed and long enough to be kept (each 2 s inside).
KEEP_S = ((0.0, 118.0), (152.0, 198.0), (482.0, 518.0), (532.0, 600.0))
#: Still and disarmed, but each side of the gap shorter than 30 s.
SHORT_BY_GAP_S = ((400.0, 420.0), (455.0, 470.0))
DEVICE_ID = 2490378  # a PX4 DeviceStructure: SPI bus 1, address 0, devtype 0x26


@dataclass(frozen=True)
class Flight:
    time_s: NDArray[np.float64]
    rates_dps: NDArray[np.float64]  # (n, 3)
    accel_mps2: NDArray[np.float64]  # (n, 3)
    temperature_c: NDArray[np.float64]
    armed: NDArray[np.bool_]


def flight(seed: int = 18, *, duration_s: float = 600.0) -> Flight:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    kind = np.full(len(t), "still", dtype=object)
    for a, b, what in SCHEDULE:
        kind[(t >= a) & (t < b)] = what
    keep_row = kind != "gap"
    temp = 25.0 + 15.0 * (1.0 - np.exp(-t / 300.0))
    rates = rng.standard_normal((len(t), 3)) * 0.05 + np.array([0.3, -0.2, 0.1])
    rates += 0.01 * (temp - 25.0)[:, None]  # a thermal bias slope, 0.01 °/s/°C
    acc = rng.standard_normal((len(t), 3)) * 0.03 + np.array([0.0, 0.0, -G_MPS2])
    for a, b, what in SCHEDULE:
        m = (t >= a) & (t < b)
        u = (t[m] - a) / (b - a)
        if what == "turn":
            rates[m, 2] += 90.0 * np.sin(np.pi * u)
            acc[m] += rng.standard_normal((int(m.sum()), 3)) * 1.5
        elif what == "idle":
            rates[m] += rng.standard_normal((int(m.sum()), 3)) * 0.3
            acc[m] += rng.standard_normal((int(m.sum()), 3)) * 1.0
        elif what == "fly":
            rates[m, 0] += 180.0 * np.sin(2 * np.pi * 4 * u) * np.sin(np.pi * u)
            rates[m, 1] += 60.0 * np.sin(2 * np.pi * 7 * u)
            yaw = (t[m] >= 300.0) & (t[m] < 330.0)  # a constant-rate yaw, 20 °/s
            rates[np.flatnonzero(m)[yaw], 2] += 20.0
            acc[m] += rng.standard_normal((int(m.sum()), 3)) * 3.0
    armed = np.isin(kind, ["idle", "fly"])
    return Flight(time_s=t[keep_row], rates_dps=rates[keep_row], accel_mps2=acc[keep_row],
                  temperature_c=temp[keep_row], armed=armed[keep_row])


def still_flight(duration_s: float = 20.0, seed: int = 5) -> Flight:
    """A log of ``duration_s`` on the ground, still and disarmed throughout."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    rates = rng.standard_normal((len(t), 3)) * 0.05 + np.array([0.3, -0.2, 0.1])
    acc = rng.standard_normal((len(t), 3)) * 0.03 + np.array([0.0, 0.0, -G_MPS2])
    return Flight(time_s=t, rates_dps=rates, accel_mps2=acc, temperature_c=30.0 + 0.05 * t,
                  armed=np.zeros(len(t), dtype=bool))


STATUS_FIELDS = [("uint64_t", "timestamp"), ("uint8_t", "arming_state")]
BOOT_US = 5_000_000  # the log starts 5 s after boot


def _state_changes(f: Flight) -> list[tuple[int, bool]]:
    """(µs, armed) at the start and at each change of the arming state."""
    idx = np.concatenate(([0], np.flatnonzero(np.diff(f.armed.astype(np.int8))) + 1))
    return [(BOOT_US + round(float(f.time_s[i]) * 1e6), bool(f.armed[i])) for i in idx]


def ulog(f: Flight) -> bytes:
    """sensor_gyro 0 (id 0), sensor_accel 0 (id 1), vehicle_status (id 2, every 0.5 s as
    PX4 publishes it, arming_state 2 armed, 1 standby)."""
    out = uk.header_and_definitions() + uk._format("vehicle_status", STATUS_FIELDS)
    out += uk._msg(b"A", struct.pack("<BH", 0, 0) + b"sensor_gyro")
    out += uk._msg(b"A", struct.pack("<BH", 0, 1) + b"sensor_accel")
    out += uk._msg(b"A", struct.pack("<BH", 0, 2) + b"vehicle_status")
    us = BOOT_US + np.round(f.time_s * 1e6).astype(np.int64)
    rad = np.radians(f.rates_dps)
    status_t = np.arange(BOOT_US, int(us[-1]) + 1, 500_000)
    for ts in status_t:  # each state as of its time stamp
        k = max(0, int(np.searchsorted(us, ts, side="right")) - 1)
        out += uk._msg(b"D", struct.pack("<H", 2) + uk._pack(
            STATUS_FIELDS, [int(ts), 2 if f.armed[k] else 1]))
    for i, u in enumerate(us):
        out += uk._msg(b"D", struct.pack("<H", 0) + uk._pack(uk.GYRO_FIELDS, [
            int(u) + 300, int(u), DEVICE_ID, *map(float, rad[i]), float(f.temperature_c[i]),
            0]))
        out += uk._msg(b"D", struct.pack("<H", 1) + uk._pack(uk.ACCEL_FIELDS, [
            int(u) + 300, int(u), DEVICE_ID, *map(float, f.accel_mps2[i]),
            float(f.temperature_c[i]), 0]))
    return out


ARM = dfk.DFFormat(0x90, "ARM", 0, "QBIBB", "TimeUS,ArmState,ArmChecks,Forced,Method")
EV = dfk.DFFormat(0x91, "EV", 0, "QB", "TimeUS,Id")


def dataflash(f: Flight, *, arming: str = "ARM") -> bytes:
    """IMU instance 0 and the arming state as ``ARM`` messages (ArmState 1/0) or ``EV``
    events (10 ARMED, 11 DISARMED), logged at each change (ArduPilot logs them on arming
    and disarming), not at the start when the vehicle starts disarmed."""
    msgs: list[tuple[dfk.DFFormat, list[object]]] = []
    us = BOOT_US + np.round(f.time_s * 1e6).astype(np.int64)
    rad = np.radians(f.rates_dps)
    changes = [(u, a) for u, a in _state_changes(f) if a or u != BOOT_US]
    for i, u in enumerate(us):
        while changes and changes[0][0] <= u:
            when, armed = changes.pop(0)
            msgs.append((ARM, [when, int(armed), 0, 0, 0]) if arming == "ARM" else
                        (EV, [when, 10 if armed else 11]))
        msgs.append((dfk.IMU, [int(u), 0, *map(float, rad[i]), *map(float, f.accel_mps2[i]),
                               0, 0, float(f.temperature_c[i]), 1, 1, 400, 400]))
    return dfk.log([dfk.IMU, ARM if arming == "ARM" else EV], msgs)


def write(where: Path, f: Flight, stem: str) -> dict[str, Path]:
    """The flight as ``<stem>.ulg`` and ``<stem>.bin``."""
    paths = {"ulog": where / f"{stem}.ulg", "dataflash": where / f"{stem}.bin"}
    paths["ulog"].write_bytes(ulog(f))
    paths["dataflash"].write_bytes(dataflash(f))
    return paths
