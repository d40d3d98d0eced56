"""``gyrotherm import INPUT... --out FILE_OR_DIR``: the user's data as gyrotherm run files.

Each run read (:func:`gyrotherm.readers.read_runs`) is written with
:func:`gyrotherm.codecs.write_run`, its metadata extended by the provenance:
``source_file`` (the path as given), ``source_sha256`` (of the file read),
``source_format``, ``imported_by`` (gyrotherm version) and, from the reader, the
column map and the original unit of each column (``unit_<role>``).

``--out``: a directory (it exists, or the name has no ``.csv`` suffix; created
with its parents) gets one ``<run name>.csv`` per run (``:`` in a name becomes
``-``, any other character outside ``A-Za-z0-9._-`` ``_``, as ``fit`` names
calibrations: glob-safe); a ``.csv`` file name takes exactly one run.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from gyrotherm import __version__
from gyrotherm._errors import ConfigError, RunFileError
from gyrotherm.cli import _conventions as conv
from gyrotherm.cli import _pool, _prep
from gyrotherm.cli._fitrest import run_file_stem
from gyrotherm.cli._inputs import add_input_options
from gyrotherm.codecs import Run, write_run


def _with_provenance(run: Run) -> Run:
    meta = dict(run.metadata)
    meta.update({
        "source_file": run.source,
        "source_sha256": run.sha256,
        "source_format": meta.get("source_format", meta.get("format", "")),
        "imported_by": f"gyrotherm {__version__}",
    })
    return replace(run, metadata=meta)


def _targets(out: Path, runs: list[Run]) -> list[Path]:
    if out.is_dir() or out.suffix.lower() != ".csv":
        names = [run_file_stem(r.name) for r in runs]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise RunFileError(f"--out {out}: several runs would be written to the same "
                               f"file name {dupes}; import them into separate directories")
        return [out / f"{n}.csv" for n in names]
    if len(runs) != 1:
        raise ConfigError(f"--out {out}: the inputs hold {len(runs)} runs "
                          f"({', '.join(r.name for r in runs)}): give a directory")
    return [out]


def cmd_import(args: argparse.Namespace) -> int:
    conv.check_json_target(args.json)
    loaded = _prep.load(args, _prep.prep_from_args(args))  # read on the workers (--jobs)
    runs = loaded.runs
    out = Path(args.out)
    targets = _targets(out, runs)
    if args.json not in (None, conv.STDOUT) and Path(args.json).resolve() in {
            p.resolve() for p in targets}:
        raise ConfigError(f"--json {args.json}: that is one of the run files this import "
                          "writes; give the JSON another name")
    written = []
    for run, path in zip(runs, targets, strict=True):
        path.parent.mkdir(parents=True, exist_ok=True)
        write_run(_with_provenance(run), path, exact=True)  # reads back bit for bit
        t_lo, t_hi = float(run.temperature_c.min()), float(run.temperature_c.max())
        fmt = run.metadata.get("format", "?")
        written.append({"path": str(path), "run": run.name, "rows": len(run),
                        "axes": list(run.axes), "temperature_c": [t_lo, t_hi],
                        "source": run.source, "format": fmt,
                        "device_id": run.metadata.get("device_id", "")})
        if not args.json:
            print(f"wrote {path} ({len(run)} rows, axes {','.join(run.axes)}, "
                  f"{t_lo:.2f}…{t_hi:.2f} °C, from {run.source} [{fmt}])")
    if args.json:
        conv.emit_json({"written": written}, args.json)
    return loaded.exit_status  # 2 when a log failed (the others written)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("import", help="convert your own data into gyrotherm run files",
                       description="Read delimited text, candump logs or flight logs and "
                       "write gyrotherm run files (CSV version 1) with provenance metadata.")
    p.add_argument("runs", nargs="+", metavar="INPUT",
                   help="files to import (a rosbag2 directory counts as one)")
    p.add_argument("--out", required=True, metavar="FILE_OR_DIR",
                   help="a .csv file (exactly one run) or a directory (one file per run; "
                   "created with its parents)")
    conv.add_json_option(p, what="the run files written (path, run, rows, axes, °C range, "
                         "source, format, device id)")
    add_input_options(p)
    _pool.add_worker_options(p)
    p.set_defaults(func=cmd_import)
