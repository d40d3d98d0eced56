"""The ``gyrotherm`` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from gyrotherm import __version__
from gyrotherm.cli import _conventions, _run
from gyrotherm.cli._guard import run_command

_GLOBAL_FLAGS = ("-q", "--quiet", "--debug")
"""Options of ``gyrotherm`` itself that may stand before the subcommand."""


def build_parser(*, run_only: bool = False) -> argparse.ArgumentParser:
    """The command line; ``run_only``: with the ``run`` subcommand alone (what ``gyrotherm
    run`` parses, so the daemon's start-up imports none of the offline commands' modules:
    issue 22, tests/daemon/test_vehicle_imports.py)."""
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
    if run_only:
        _run.register(sub)
        return _conventions.apply(parser)
    from gyrotherm.cli import (
        _demo,
        _diagnose,
        _export,
        _fleet,
        _import,
        _learn,
        _learnstatus,
        _offline,
    )

    _offline.register(sub)
    _run.register(sub)
    _diagnose.register(sub)
    _demo.register(sub)
    _import.register(sub)
    _export.register(sub)
    _fleet.register(sub)
    _learn.register(sub)
    _learnstatus.register(sub)
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
    args_list = _learn_status_alias(args_list)
    if _is_run(args_list):
        _run.preload()  # the daemon's dependencies, first and near the bottom of the stack
    args = parse_args(args_list)
    return run_command(args.func, args, args_list)  # one line per failure (cli._guard)


def parse_args(args_list: Sequence[str]) -> argparse.Namespace:
    """Parse a command line as :func:`main` does: ``gyrotherm [-q] [--debug] run ...``
    with the ``run`` parser alone, anything else with every subcommand's."""
    return build_parser(run_only=_is_run(args_list)).parse_args(args_list)


def _learn_status_alias(args_list: list[str]) -> list[str]:
    """``gyrotherm [flags] learn status ...`` is ``learn-status ...`` (``learn`` itself
    takes logs: a log named ``status`` is given as ``./status``)."""
    i = 0
    while i < len(args_list) and args_list[i] in _GLOBAL_FLAGS:
        i += 1
    if args_list[i:i + 2] == ["learn", "status"]:
        return [*args_list[:i], "learn-status", *args_list[i + 2:]]
    return args_list


def _is_run(args_list: Sequence[str]) -> bool:
    """Whether the command line is ``gyrotherm [-q] [--debug] run ...``."""
    i = 0
    while i < len(args_list) and args_list[i] in _GLOBAL_FLAGS:
        i += 1
    return list(args_list[i:i + 1]) == ["run"]


__all__ = ["build_parser", "main", "parse_args"]
