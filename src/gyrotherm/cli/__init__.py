"""The ``gyrotherm`` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from gyrotherm import __version__
from gyrotherm._errors import GyrothermError
from gyrotherm.cli import _offline, _run


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
    demo = sub.add_parser("demo", help="the main job on embedded defaults")
    demo.add_argument("--seed", type=int, default=1)
    demo.add_argument("--rate-hz", type=float, default=10.0)
    demo.add_argument("--axis", choices=("x", "y", "z"), default="x")
    demo.add_argument("--out", default=None)
    demo.set_defaults(func=_offline.cmd_paper)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code: int = args.func(args)
    except GyrothermError as exc:
        print(f"gyrotherm: error: {exc}", file=sys.stderr)
        return 2
    return code


__all__ = ["build_parser", "main"]
