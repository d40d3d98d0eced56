"""Which reader reads a file: :func:`read_runs`.

With ``format="auto"``, decided per path by content, not by name:

1. a directory holding ``metadata.yaml`` → ``rosbag`` (rosbag2);
2. a file's first bytes: ``ULog\x01\x12\x35`` → ``ulog`` (PX4); ``\xa3\x95`` →
   ``dataflash`` (ArduPilot); ``\x89MCAP``, ``SQLite format 3\0`` (rosbag2 ``.db3``)
   or ``#ROSBAG V2.0`` (ROS 1) → ``rosbag``; ``# gyrotherm-run:`` → ``run``;
3. an empty file → by its suffix (``.ulg``, ``.bin``, ``.mcap``, ``.db3``, ``.bag``),
   so the error names the format the user meant; a DataFlash text log (first line
   ``FMT, ...``) is refused with one line;
4. first non-empty line ``(<seconds>) <iface> <id>#<data>`` → ``candump``;
5. anything else → ``text`` (delimited text, :mod:`gyrotherm.readers._text`).

Every run gets the metadata keys ``format``, ``device_id`` (a string, empty when
the source does not tell) and ``instance`` (its index among the file's runs).
The ulog, dataflash and rosbag readers live in their own modules, imported only
when such a file is read.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from types import ModuleType

from gyrotherm._errors import RunFileError
from gyrotherm.codecs import DEFAULT_DBC_PATH, Run, SignalMap, read_run, run_from_candump
from gyrotherm.codecs._candump_run import is_candump_log
from gyrotherm.readers._magic import HEAD_BYTES, content_kind
from gyrotherm.readers._spec import InputSpec
from gyrotherm.readers._text import read_text

FORMATS = ("auto", "run", "text", "candump", "ulog", "dataflash", "rosbag")
"""Values of ``InputSpec.format`` / ``--format``."""
_FORMAT_OF_KIND = {"ulog": "ulog", "dataflash": "dataflash", "mcap": "rosbag",
                   "sqlite": "rosbag", "ros1": "rosbag", "run": "run"}
"""A file's content kind (:func:`gyrotherm.readers._magic.content_kind`) → its reader.
A run file with a BOM has no kind: codecs.read_run refuses it, it is read as text."""
_SUFFIX = {".ulg": "ulog", ".bin": "dataflash", ".mcap": "rosbag", ".db3": "rosbag",
           ".bag": "rosbag"}


def detect_format(path: str | os.PathLike[str]) -> str:
    """The format ``read_runs`` picks for ``path`` with ``format="auto"`` (module docstring)."""
    p = Path(path)
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag"
        raise RunFileError(f"{p}: a directory, but not a rosbag2 one (no metadata.yaml)")
    if not p.exists():  # read_runs says so; the name tells what was meant
        return _SUFFIX.get(p.suffix.lower(), "text")
    try:
        with p.open("rb") as fh:
            head = fh.read(HEAD_BYTES)
    except OSError as exc:
        raise RunFileError(f"{p}: cannot read: {exc.strerror}") from exc
    kind = content_kind(p, head)
    if kind:
        return _FORMAT_OF_KIND[kind]
    if not head:
        by_suffix = _SUFFIX.get(p.suffix.lower())
        if by_suffix:
            return by_suffix
        raise RunFileError(f"{p}: the file is empty (0 bytes); give a file with data")
    if head.startswith(b"FMT,"):
        raise RunFileError(f"{p}: an ArduPilot DataFlash text log (first line 'FMT, ...'), "
                           "which gyrotherm does not read; give the binary .bin log the "
                           "autopilot wrote (its SD card's APM/LOGS, or download it)")
    return "candump" if is_candump_log(p) else "text"


def _module(fmt: str, name: str, path: Path) -> ModuleType:
    try:
        return importlib.import_module(f"gyrotherm.readers.{name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"gyrotherm.readers.{name}":
            raise RunFileError(f"{path}: format {fmt!r}: this gyrotherm has no {fmt} reader "
                               f"(module gyrotherm.readers.{name} is missing)") from exc
        raise RunFileError(f"{path}: format {fmt!r} needs the Python package "
                           f"{exc.name!r}: pip install it") from exc


def _candump(path: Path, spec: InputSpec) -> list[Run]:
    from gyrotherm.codecs._canmap import resolve_layout

    dbc = spec.dbc or DEFAULT_DBC_PATH
    signals = spec.signals or SignalMap.default()
    run = run_from_candump(path, dbc_path=dbc, signal_map=signals)
    rate_id = resolve_layout(dbc, signals).rate.frame_id
    return [_tag(run, "candump", device_id=f"can:0x{rate_id:X}")]


def _tag(run: Run, fmt: str, *, device_id: str = "", instance: int = 0,
         override: bool = False) -> Run:
    """``run`` with the metadata keys ``format``, ``device_id``, ``instance`` (the
    reader's own values kept, except ``format`` when ``override``)."""
    meta = dict(run.metadata)
    if override:
        meta["format"] = fmt
    meta.setdefault("format", fmt)
    meta.setdefault("device_id", device_id)
    meta.setdefault("instance", str(instance))
    return replace(run, metadata=meta)


def read_runs(path: str | os.PathLike[str], *, spec: InputSpec) -> list[Run]:
    """Every run in ``path`` (several for a log with several IMUs), read as ``spec`` says.

    Raises :class:`gyrotherm.RunFileError` naming the file (and line, column) on
    bad input, and for an unknown ``spec.format`` or a reader not installed.
    """
    p = Path(path)
    fmt = detect_format(p) if spec.format == "auto" else spec.format
    readers: dict[str, Callable[[], list[Run]]] = {
        # an imported run file keeps its original format in source_format
        "run": lambda: [_tag(read_run(p), "run", override=True)],
        "text": lambda: read_text(p, columns=spec.columns, delimiter=spec.delimiter,
                                  bad_lines=spec.bad_lines),
        "candump": lambda: _candump(p, spec),
        "ulog": lambda: list(_module(fmt, "_ulog", p).read_ulog(p)),
        "dataflash": lambda: list(_module(fmt, "_dataflash", p).read_dataflash(p)),
        "rosbag": lambda: list(_module(fmt, "_rosbag", p).read_rosbag(
            p, imu_topic=spec.imu_topic, temperature_topic=spec.temperature_topic)),
    }
    reader = readers.get(fmt)
    if reader is None:
        raise RunFileError(f"{p}: unknown format {fmt!r}; known: {', '.join(FORMATS)}")
    if not p.exists():
        raise RunFileError(f"{p}: no such file")
    if p.is_file() and p.stat().st_size == 0:
        raise RunFileError(f"{p}: the file is empty (0 bytes; format {fmt!r} by its name): "
                           "a log cut before anything was written; give the complete file")
    runs = reader()
    if not runs:
        raise RunFileError(f"{p}: format {fmt!r}: no run in the file")
    return [_tag(r, fmt, instance=i) for i, r in enumerate(runs)]
