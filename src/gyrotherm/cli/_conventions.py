"""One set of command-line conventions for every ``gyrotherm`` subcommand.

* ``--json [FILE]``: JSON to stdout without FILE (or with ``-``), to FILE otherwise
  (parent directories created); where the command prints a table, JSON replaces it.
* ``-q/--quiet`` accepted before and after the subcommand (:func:`apply`).
* Every option's help shows its default (:class:`DefaultsFormatter`).
* Outputs: parent directories created (:func:`output_path`), a run file is never
  overwritten by an output (:func:`output_path`), and arguments given in the wrong
  order are caught with a hint (:func:`check_calibration_first`, :func:`check_runs`).

Imports nothing beyond the standard library: ``gyrotherm run`` builds this parser too
(tests/cli/test_footprint.py).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from gyrotherm._errors import ConfigError

#: ``--json`` without a file: stdout.
STDOUT = "-"
_SNIFF_BYTES = 4096
#: File name endings of logs that hold runs (run files, candump logs, flight logs).
RUN_SUFFIXES = (".csv", ".log", ".txt", ".ulg", ".bin", ".mcap", ".db3")
_LOG_SUFFIXES = (".csv", ".ulg", ".bin", ".mcap", ".db3")  # never an output's name


class DefaultsFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions kept as written; each option's help ends with its default unless
    the help text already names it ("default ...") or the option is a flag."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text.lower() or not action.option_strings or action.required:
            return text
        if action.nargs == 0 or action.default in (None, argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


def add_json_option(parser: argparse.ArgumentParser, *, what: str) -> None:
    """``--json [FILE]``: ``what`` as JSON, to stdout (no FILE, or ``-``) or FILE."""
    parser.add_argument("--json", nargs="?", const=STDOUT, default=None, metavar="FILE",
                        help=f"write {what} as JSON to FILE, or to stdout without FILE "
                        "(replaces the printed table; default: no JSON)")


def emit_json(data: Any, target: str) -> Path | None:
    """Write ``data`` for ``--json TARGET``: stdout for ``-``, else the file (parents
    created; never over a run file). Returns the file written, None for stdout."""
    from gyrotherm.cli._jsonsafe import dumps  # strict JSON: null for NaN, with why

    text = dumps(data)
    if target == STDOUT:
        print(text)
        return None
    path = output_path(target, option="--json")
    path.write_text(text + "\n", encoding="utf-8")
    return path


def check_json_target(target: str | None) -> None:
    """``--json FILE`` checked (parents created, not a run file) before any work, so
    that a bad target does not fail after other outputs were written."""
    if target is not None and target != STDOUT:
        output_path(target, option="--json")


def output_path(target: str | Path, *, option: str) -> Path:
    """``target`` ready to be written: its parent directories created; refused (with a
    hint) when it is an existing run file, which an output would destroy."""
    path = Path(target)
    if path.is_file() and (_run_content(_head(path)) or path.suffix.lower() in _LOG_SUFFIXES):
        raise ConfigError(f"{option} {path}: is an existing run file, not an output; "
                          "outputs come after the option, runs are positional "
                          f"(e.g. {option} out.json RUN...)")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def output_dir(target: str | Path, *, option: str) -> Path:
    """A directory for ``option`` (created with its parents); refused when a file."""
    path = Path(target)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {path}: is a file; {option} takes a directory")
    path.mkdir(parents=True, exist_ok=True)
    return path


def _head(path: str | Path) -> bytes:
    try:
        with Path(path).open("rb") as fh:
            return fh.read(_SNIFF_BYTES)
    except OSError:
        return b""


def looks_like_calibration(path: str | Path) -> bool:
    """A JSON object naming the calibration schema (by content, not by name)."""
    head = _head(path).lstrip(b"\xef\xbb\xbf").lstrip()
    return head.startswith(b"{") and b'"gyrotherm.calibration' in head


def looks_like_run(path: str | Path) -> bool:
    """A run file (``# gyrotherm-run``), a candump log, or a log by its file name; never
    a JSON document."""
    head = _head(path).lstrip(b"\xef\xbb\xbf").lstrip()
    if head.startswith((b"{", b"[")):
        return False
    return _run_content(head) or Path(path).suffix.lower() in RUN_SUFFIXES


def _run_content(head: bytes) -> bool:
    """A run file's magic line, a ULog header or a candump line: a run by content."""
    head = head.lstrip(b"\xef\xbb\xbf").lstrip()
    if head.startswith((b"# gyrotherm-run", b"ULog")):
        return True
    first = head.split(b"\n", 1)[0].strip()
    return first.startswith(b"(") and b"#" in first  # candump -l: (<s>) <iface> <id>#<data>


def check_calibration_first(calibration: str, runs: Sequence[str], *, command: str) -> None:
    """``gyrotherm COMMAND CAL RUNS...``: a run where the calibration belongs, or a
    calibration among the runs, is a swapped argument; say so before reading."""
    if looks_like_calibration(calibration):
        check_runs(runs, command=command)
        return
    cal_among_runs = [r for r in runs if looks_like_calibration(r)]
    if cal_among_runs or looks_like_run(calibration):
        raise ConfigError(
            f"{calibration}: the first argument looks like a run file, the calibration "
            f"comes first: gyrotherm {command} CAL RUNS..."
            + (f" (here: gyrotherm {command} {cal_among_runs[0]} {calibration} ...)"
               if cal_among_runs else ""))


def check_runs(runs: Sequence[str], *, command: str) -> None:
    """A calibration given where runs are expected: name it, with the usage."""
    for r in runs:
        if looks_like_calibration(r):
            hint = (f"gyrotherm evaluate {r} RUNS... scores it" if command != "evaluate"
                    else "gyrotherm evaluate CAL RUNS... takes one, first")
            raise ConfigError(f"{r}: is a calibration file, not a run; {hint}")


def _subparsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                yield sub
                yield from _subparsers(sub)


def walk(parser: argparse.ArgumentParser) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every parser under ``parser`` (itself excluded), with its ``prog``."""
    for sub in _subparsers(parser):
        yield sub.prog, sub


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """``-q/--quiet`` on ``parser`` unless it has one. The default is SUPPRESS so a
    ``-q`` given before the subcommand is not reset by the subcommand's parser."""
    if "--quiet" not in parser._option_string_actions:
        parser.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                            help="no progress output (also accepted before the subcommand)")


def apply(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The conventions on every subcommand of ``parser``: defaults in help, ``-q``."""
    parser.formatter_class = DefaultsFormatter
    for _, sub in walk(parser):
        sub.formatter_class = DefaultsFormatter
        add_quiet(sub)
    return parser


__all__ = [
    "STDOUT",
    "DefaultsFormatter",
    "add_json_option",
    "add_quiet",
    "apply",
    "check_calibration_first",
    "check_json_target",
    "check_runs",
    "emit_json",
    "looks_like_calibration",
    "looks_like_run",
    "output_dir",
    "output_path",
    "walk",
]
