"""``gyrotherm run --config FILE``: the streaming daemon."""

from __future__ import annotations

import argparse
import logging
import sys


def preload() -> None:
    """Import the daemon's third-party dependencies with a shallow Python stack.

    CPython 3.11 keeps frames in 16 KiB chunks that it maps and unmaps as the stack crosses
    a chunk's end. Imported deep inside gyrotherm's own imports, numpy's and the signal
    module's import-time loops sit on such a boundary and map/unmap a chunk per call:
    1 374 ``mmap``/``munmap`` pairs in ``gyrotherm run``'s start (3 861 under ``python -m``)
    against 1 in a bare import of the same modules, ≈ 20–60 ms of system time
    (docs/BENCHMARKS.md, "Footprint"). Imported here first, two frames below ``main``,
    they load as in a bare interpreter; the daemon's own imports then find them loaded.
    """
    from gyrotherm._memory import limit_arenas

    limit_arenas()  # before numpy's, zenoh's and the bus's threads start
    import can  # noqa: F401
    import cantools  # noqa: F401
    import msgpack  # noqa: F401
    import numpy  # noqa: F401
    import zenoh  # noqa: F401


def cmd_run(args: argparse.Namespace) -> int:
    from gyrotherm.daemon import Daemon, load_vehicle_config  # only `run` loads the daemon

    level = args.log_level or ("warning" if getattr(args, "quiet", False) else "info")
    logging.basicConfig(
        level=getattr(logging, level.upper()),
        stream=sys.stderr,
        format="%(levelname)s %(name)s: %(message)s",  # the journal adds the time
    )
    config = load_vehicle_config(args.config)
    if args.imu is not None:
        config = config.only(args.imu)
    daemon = Daemon(config)
    daemon.install_signal_handlers()
    summary = daemon.run()
    dropped = sum(summary.drops.values())
    print(f"frames in {summary.frames_received}, published {summary.frames_published}, "
          f"dropped {dropped} {dict(sorted(summary.drops.items()))}", flush=True)
    if config.multi:
        for name, c in summary.per_imu.items():
            print(f"{name}: frames in {c.frames_received}, published {c.frames_published}, "
                  f"dropped {sum(c.drops.values())} {dict(sorted(c.drops.items()))}", flush=True)
        print(f"bus: frames of no IMU, transport items {dict(sorted(summary.bus_drops.items()))}",
              flush=True)
    return 0


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("run", help="run the streaming daemon (CAN → compensation → Zenoh)")
    p.add_argument("--config", required=True, help="TOML config file (see docs/operations.md)")
    p.add_argument("--imu", default=None, metavar="SENSOR",
                   help="with [[imu]] tables: run only this IMU (its own process; default: "
                   "every IMU of the file in this one process)")
    p.add_argument("--log-level", default=None, choices=("debug", "info", "warning", "error"),
                   help="log level on stderr (default: info; with -q: warning)")
    p.set_defaults(func=cmd_run)
