"""``gyrotherm sim life``: a vehicle's power-ons as run files, to try ``gyrotherm learn``.

Each power-on is the simulator's gyro switched on cold at an ambient temperature drawn
uniformly over ``--ambient-c LO HI`` (seeded), left at rest while its electronics warm it
(die +8 °C, τ 120 s: :data:`gyrotherm.sim._life.LIFE_GYRO`) for ``--warmup-s``, then
optionally turning for ``--motion-s`` (rows ``gyrotherm learn`` must leave out). Time runs
from the power-on, as a PX4/ArduPilot log from boot; the truth columns are the simulator's.
The same lives as docs/findings.md §8 (``scripts/learning_study.py``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrotherm._errors import ConfigError
from gyrotherm.cli import _conventions as conv


def cmd_sim_life(args: argparse.Namespace) -> int:
    from gyrotherm.cli._offline import write_runs
    from gyrotherm.sim._life import ambients, power_on

    lo, hi = args.ambient_c
    if not (-60.0 <= lo <= hi <= 90.0):
        raise ConfigError(f"--ambient-c: expected LO ≤ HI within −60…90 °C, got {lo:g} {hi:g}")
    for name in ("warmup_s", "rate_hz"):
        if not getattr(args, name) > 0:
            raise ConfigError(f"--{name.replace('_', '-')}: expected > 0, got "
                              f"{getattr(args, name):g}")
    if args.power_ons < 1 or args.motion_s < 0:
        raise ConfigError("--power-ons: at least 1; --motion-s: at least 0")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = [power_on(a, warmup_s=args.warmup_s, motion_s=args.motion_s, rate_hz=args.rate_hz,
                     seed=args.seed * 1000 + k, name=f"power-on-{args.seed}-{k:02d}")
            for k, a in enumerate(ambients(args.power_ons, ambient_range_c=(lo, hi),
                                           seed=args.seed))]
    return write_runs(runs, out, args.json)


def register(sim_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sim_sub.add_parser("life", help="simulate a vehicle's power-ons (warm-ups at rest) "
                           "into run files, for 'gyrotherm learn'")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="DIRECTORY for the run files, one per power-on (created)")
    p.add_argument("--power-ons", type=int, default=10,
                   help="power-ons, each from its own ambient (default 10)")
    p.add_argument("--ambient-c", type=float, nargs=2, default=(-10.0, 40.0),
                   metavar=("LO", "HI"), help="ambient range, °C (default −10 40)")
    p.add_argument("--warmup-s", type=float, default=600.0,
                   help="at rest after each power-on, s (default 600)")
    p.add_argument("--motion-s", type=float, default=0.0,
                   help="then turning, s (default 0)")
    p.add_argument("--rate-hz", type=float, default=10.0, help="sample rate, Hz (default 10)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    conv.add_json_option(p, what="the files written (path, rows, duration_s)")
    p.set_defaults(func=cmd_sim_life)
