"""Servo-loop example: damp the yaw rate with the daemon's thermally corrected gyro rate.

    python examples/servo_loop.py --vehicle rover1 --sensor imu0 \
        --connect tcp/127.0.0.1:7447 --max-samples 1000 --timeout-s 2

Each rate message gives one command ``command_dps = -gain · rate_dps[z]`` (°/s).
The loop stops after ``--max-samples`` messages, or when none arrives for
``--timeout-s`` seconds (a watchdog: exit status 1 then).
"""

from __future__ import annotations

import argparse

from gyrotherm.client import Subscriber


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicle", default="rover1")
    p.add_argument("--sensor", default="imu0")
    p.add_argument("--connect", action="append", default=None, help="zenoh endpoint")
    p.add_argument("--gain", type=float, default=2.0, help="proportional gain (1)")
    p.add_argument("--max-samples", type=int, default=1000)
    p.add_argument("--timeout-s", type=float, default=2.0, help="watchdog, s")
    a = p.parse_args(argv)

    # ---- the servo loop itself ------------------------------------------------
    n = 0
    with Subscriber(a.vehicle, a.sensor, connect=a.connect or ["tcp/127.0.0.1:7447"]) as sub:
        for msg in sub.rates(timeout_s=a.timeout_s):  # typed RateMessage, corrected rates
            command_dps = -a.gain * msg.rate_dps[2]  # yaw-rate damping
            print(f"seq={msg.seq} yaw_dps={msg.rate_dps[2]:.6f} command_dps={command_dps:.6f}"
                  f" flags={int(msg.flags)}", flush=True)  # fmt: skip
            n += 1
            if n >= a.max_samples:
                break
        gaps = sub.stats().rate.gaps
    print(f"done: {n} samples, {gaps} gaps")
    return 0 if n >= a.max_samples else 1


if __name__ == "__main__":
    raise SystemExit(main())
