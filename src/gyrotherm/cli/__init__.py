"""The ``gyrotherm`` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from gyrotherm import __version__
from gyrotherm.cli import _conventions, _demo, _diagnose, _export, _import, _offline, _run
from gyrotherm.cli._guard import run_command


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyrotherm",
        description="Thermal zero-bias compensation for MEMS gyroscopes (T and ΔT models).",
    )
    parser.add_argument("--version", action="version", version=f"gyrotherm {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    parser.add_argument("--debug", action="store_true",
                        help="let an unexpected error through with its traceback "
                        "(default: one line and the file holding the traceback)")
    sub = parser.add_subparsers(dest="command", required=True)
    _offline.register(sub)
    _run.register(sub)
    _diagnose.register(sub)
    _demo.register(sub)
    _import.register(sub)
    _export.register(sub)
    sub.add_parser("listen", help="live view of a sensor's Zenoh stream (see: listen --help)")
    sub.add_parser("record", help="record to MCAP (ROS 2 Imu) / serve Foxglove / "
                   "publish over rmw_zenoh (record --help)")
    return _conventions.apply(parser)  # defaults in every help, -q after the subcommand


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    quiet = args_list[:1] in (["-q"], ["--quiet"])
    if args_list[quiet:quiet + 1] == ["listen"]:  # the live view has its own parser
        from gyrotherm.client import listen_main

        return listen_main(args_list[quiet + 1:], quiet=quiet,
                           formatter_class=_conventions.DefaultsFormatter)
    if args_list[quiet:quiet + 1] == ["record"]:  # client side, own parser; mcap lazily
        from gyrotherm.client._record import record_main

        return record_main(args_list[quiet + 1:] + (["-q"] if quiet else []),
                           formatter_class=_conventions.DefaultsFormatter)
    parser = build_parser()
    args = parser.parse_args(args_list)
    return run_command(args.func, args, args_list)  # one line per failure (cli._guard)


__all__ = ["build_parser", "main"]
