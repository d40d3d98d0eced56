"""The ``gyrotherm`` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from gyrotherm import __version__
from gyrotherm._errors import GyrothermError
from gyrotherm.cli import _conventions, _demo, _diagnose, _export, _import, _offline, _run


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyrotherm",
        description="Thermal zero-bias compensation for MEMS gyroscopes (T and ΔT models).",
    )
    parser.add_argument("--version", action="version", version=f"gyrotherm {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")
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
    try:
        code: int = args.func(args)
    except GyrothermError as exc:
        print(f"gyrotherm: error: {exc}", file=sys.stderr)
        return 2
    return code


__all__ = ["build_parser", "main"]
