"""What the command line prints when a command fails: one line, never a stack.

* :class:`gyrotherm.GyrothermError` (bad input, refused fit, …): ``gyrotherm: error:
  <message>``, exit 2. The message names the file, what is wrong and what to do; one
  that names none of the command's input files (a run name, an option) gets them
  in front (``a.ulg, b.ulg: <message>``).
* :class:`OSError` (a file that cannot be read or written, a full disk):
  ``gyrotherm: error: <file>: <reason>``, exit 2.
* anything else is a bug in gyrotherm: one line naming the exception and the file
  holding the full traceback (``$XDG_STATE_HOME/gyrotherm/``, else
  ``~/.local/state/gyrotherm/``, else the temporary directory), exit
  :data:`EXIT_INTERNAL_ERROR`. ``gyrotherm --debug …`` (or ``GYROTHERM_DEBUG=1``)
  lets every exception through with its traceback instead.
* Ctrl-C: ``gyrotherm: interrupted``, exit 130.

``gyrotherm run`` (the daemon) keeps an unexpected exception's traceback on stderr as
before: systemd's journal records it.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path

from gyrotherm._errors import GyrothermError

EXIT_USER_ERROR = 2
"""Bad input or a refusal: the message says what to do."""
EXIT_INTERNAL_ERROR = 70
"""An unexpected exception: a bug (``EX_SOFTWARE`` of sysexits.h)."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (128 + SIGINT), as a shell reports it."""
DEBUG_ENV = "GYROTHERM_DEBUG"
KEEP_TRACEBACK_COMMANDS = frozenset({"run"})
"""The daemon: under systemd its journal is where the traceback belongs."""


def _log_dirs() -> list[Path]:
    state = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return [Path(state) / "gyrotherm", Path(tempfile.gettempdir())]


def write_traceback(exc: BaseException, argv: list[str]) -> Path | None:
    """The traceback of ``exc`` and the command line in a new file; its path (None when
    no directory could take it)."""
    text = (f"gyrotherm {' '.join(argv)}\n\n"
            + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    name = f"gyrotherm-crash-{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}.log"
    for directory in _log_dirs():
        try:
            directory.mkdir(parents=True, exist_ok=True)
            path = directory / name
            path.write_text(text, encoding="utf-8")
            return path
        except OSError:
            continue
    return None


def _os_error_line(exc: OSError) -> str:
    where = exc.filename if exc.filename is not None else "a file"
    return f"{where}: {exc.strerror or exc}"


def _naming_inputs(message: str, args: argparse.Namespace) -> str:
    inputs = [str(p) for p in getattr(args, "runs", None) or []]
    if not inputs or any(p in message or Path(p).name in message for p in inputs):
        return message
    return f"{', '.join(inputs)}: {message}"


def run_command(func: Callable[[argparse.Namespace], int], args: argparse.Namespace,
                argv: list[str]) -> int:
    """``func(args)`` with the failures of the module docstring turned into one line."""
    debug = bool(getattr(args, "debug", False)) or os.environ.get(DEBUG_ENV, "") not in ("", "0")
    try:
        return func(args)
    except GyrothermError as exc:
        if debug:
            raise
        print(f"gyrotherm: error: {_naming_inputs(str(exc), args)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        if debug:
            raise
        print("gyrotherm: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:
        if debug:
            raise
        print(f"gyrotherm: error: {_os_error_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except Exception as exc:
        if debug or getattr(args, "command", None) in KEEP_TRACEBACK_COMMANDS:
            raise
        path = write_traceback(exc, argv)
        where = f"the traceback is in {path}" if path else "no file could take the traceback"
        first = str(exc).splitlines()[0] if str(exc) else ""
        print(f"gyrotherm: internal error (a bug, please report it): "
              f"{type(exc).__name__}: {first[:200]}; {where}; rerun with "
              f"`gyrotherm --debug ...` to see it here", file=sys.stderr)
        return EXIT_INTERNAL_ERROR


__all__ = ["DEBUG_ENV", "EXIT_INTERNAL_ERROR", "EXIT_INTERRUPTED", "EXIT_USER_ERROR", "run_command",
           "write_traceback"]
