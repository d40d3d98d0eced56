"""Reading and preparing many logs on workers (:mod:`gyrotherm.cli._pool`) for ``fit``,
``import``, ``diagnose`` and ``fleet``: :func:`load`.

One task per log (:func:`prepare_log`, run by a worker): read it
(:func:`gyrotherm.readers.read_runs`), and for the runs of the selected devices run rest
detection and estimate T and ΔT (:func:`gyrotherm.compensation.features`) when the
command asks. What comes back is compact: the arrays the command uses, and for ``fit``
and ``fleet`` each run's header (metadata, name, source: no rows) instead of the run.

A log that fails (unreadable, bad content, a quality the reader refuses) is one line
``gyrotherm: error: <log>: <why>`` on stderr, as any failure of the command line
(:mod:`gyrotherm.cli._guard`), and the others go on: :attr:`Loaded.exit_status` is
then 2 (:data:`~gyrotherm.cli._guard.EXIT_USER_ERROR`) once the command has written
what the good logs give. When every log fails, the last line is the command's error.
"""

from __future__ import annotations

import argparse
import functools
import os
import resource
import socket
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from gyrotherm._errors import GyrothermError, RunFileError
from gyrotherm.cli import _drift, _pool
from gyrotherm.cli._common import damage_notes, progress
from gyrotherm.cli._fitrest import rest_config, rest_of
from gyrotherm.cli._guard import EXIT_USER_ERROR
from gyrotherm.cli._identity import select_devices
from gyrotherm.cli._inputs import spec_from_args
from gyrotherm.codecs import Run
from gyrotherm.compensation._rest import RestConfig, RestReport
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.readers import InputSpec, read_runs

if TYPE_CHECKING:  # compensation._fit and analysis are imported by the workers when needed
    from gyrotherm.analysis._readout_estimator import RunReadout
    from gyrotherm.compensation import RunFeatures


@dataclass(frozen=True)
class Prep:
    """What a worker does with each log (pickled to it)."""

    spec: InputSpec
    devices: tuple[str, ...] = ()
    """``--device``: prepare only these devices' runs (all when empty)."""
    rest: RestConfig | None = None
    """Rest detection with these thresholds (None: ``--rest all``, none)."""
    estimator: EstimatorConfig | None = None
    """Estimate T and ΔT with this estimator (None: not needed)."""
    device_estimators: tuple[tuple[str, EstimatorConfig], ...] = ()
    """(device id, estimator) pairs: a run of a device listed here is estimated with its
    own (``fit`` choosing each device's estimator from its readout), the others with
    ``estimator``."""
    imu_estimators: tuple[tuple[tuple[str, str, str], EstimatorConfig], ...] = ()
    """((vehicle id, device id, sensor id), estimator) pairs, looked up before
    ``device_estimators`` (``fleet`` choosing each IMU's estimator from its readout)."""
    keep_rows: bool = True
    """Return whole runs; False: headers only (``Run.slice(0, 0)``)."""
    readout: bool = False
    """Characterise each run's temperature readout (``fit`` choosing its estimator:
    :mod:`gyrotherm.analysis._readout_estimator`)."""
    debug: bool = False
    """Let an unexpected exception through (``gyrotherm --debug``)."""


@dataclass(frozen=True)
class LogResult:
    """One log's result: its runs (or headers) and, per run, the rest report and
    features (None for a device not selected), or the error line."""

    path: str
    runs: tuple[Run, ...] = ()
    reports: tuple[RestReport | None, ...] = ()
    features: tuple[RunFeatures | None, ...] = ()
    readouts: tuple[RunReadout | None, ...] = ()
    notes: tuple[str, ...] = ()
    error: str = ""
    worker: str = ""
    """``host:pid`` of the process that read it."""
    peak_rss_mb: float = 0.0
    """That process' peak resident memory after the log, MB."""


def _where() -> tuple[str, float]:
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux
    return f"{socket.gethostname()}:{os.getpid()}", round(rss, 1)


def error_line(path: str, exc: BaseException) -> str:
    """The one-line message of a failed log, naming it (as :mod:`._guard` words it)."""
    if isinstance(exc, OSError) and not isinstance(exc, GyrothermError):
        where = exc.filename if exc.filename is not None else path
        return f"{where}: {exc.strerror or exc}"
    text = str(exc) if isinstance(exc, GyrothermError) else (
        f"internal error (a bug, please report it; rerun with `gyrotherm --debug ...` "
        f"to see its traceback): {type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
        if str(exc) else f"internal error (a bug): {type(exc).__name__}")
    return text if (path in text or Path(path).name in text) else f"{path}: {text}"


def _estimator_of(run: Run, prep: Prep) -> EstimatorConfig:
    """The estimator for ``run``: its IMU's, else its device's, else ``prep.estimator``."""
    chosen = dict(prep.imu_estimators).get(_drift.identity(run.metadata))
    if chosen is None:
        chosen = dict(prep.device_estimators).get(run.metadata.get("device_id", ""))
    assert prep.estimator is not None
    return chosen or prep.estimator


def prepare_log(path: str, prep: Prep) -> LogResult:
    """Read and prepare one log (module docstring); never raises for the log's own
    errors (without ``prep.debug``): they are the result's ``error``."""
    try:
        runs = read_runs(path, spec=prep.spec)
        wanted = [not prep.devices or r.metadata.get("device_id", "") in prep.devices
                  for r in runs]
        reports = tuple(rest_of(r, prep.rest) if w and prep.rest else None
                        for r, w in zip(runs, wanted, strict=True))
        feats: tuple[RunFeatures | None, ...] = ()
        if prep.estimator is not None:
            from gyrotherm.compensation import features

            feats = tuple(features(r, _estimator_of(r, prep)) if w else None
                          for r, w in zip(runs, wanted, strict=True))
        readouts: tuple[RunReadout | None, ...] = ()
        if prep.readout:
            from gyrotherm.analysis._readout_estimator import run_readout

            readouts = tuple(run_readout(r) if w else None  # None: too short
                             for r, w in zip(runs, wanted, strict=True))
        notes = tuple(damage_notes(path, runs))
        kept = tuple(runs if prep.keep_rows else (r.slice(0, 0) for r in runs))
    except Exception as exc:
        if prep.debug and not isinstance(exc, GyrothermError | OSError):
            raise
        worker, rss = _where()
        return LogResult(path, error=error_line(path, exc), worker=worker, peak_rss_mb=rss)
    worker, rss = _where()
    return LogResult(path, kept, reports, feats, readouts, notes, worker=worker,
                     peak_rss_mb=rss)


def _lost(path: str, why: str) -> LogResult:
    return LogResult(path, error=f"{path}: {why}")


@dataclass(frozen=True)
class Loaded:
    """Every log's runs in input order, aligned per run with ``reports`` (empty with
    ``--rest all``) and ``features`` (empty when not asked); the failed logs."""

    runs: list[Run]
    reports: list[RestReport]
    features: list[RunFeatures]
    failed: list[str]
    workers: dict[str, float]
    """Peak RSS (MB) per worker process that read a log."""
    readouts: list[RunReadout] = field(default_factory=list)
    """Per run, its readout (``Prep.readout``; empty when not asked)."""
    paths: list[str] = field(default_factory=list)
    """The logs that were read, in input order (the failed ones left out)."""

    @property
    def exit_status(self) -> int:
        """0, or 2 when a log failed (the good ones' outputs are written)."""
        return EXIT_USER_ERROR if self.failed else 0


def prep_from_args(args: argparse.Namespace, *, estimator: EstimatorConfig | None = None,
                   keep_rows: bool = True, readout: bool = False,
                   device_estimators: dict[str, EstimatorConfig] | None = None,
                   imu_estimators: dict[tuple[str, str, str], EstimatorConfig] | None = None,
                   ) -> Prep:
    rest = None if getattr(args, "rest", "all") == "all" or readout else rest_config(args)
    return Prep(spec=spec_from_args(args), devices=tuple(getattr(args, "device", None) or ()),
                rest=rest, estimator=estimator, keep_rows=keep_rows, readout=readout,
                device_estimators=tuple((device_estimators or {}).items()),
                imu_estimators=tuple((imu_estimators or {}).items()),
                debug=bool(getattr(args, "debug", False)))


def load(args: argparse.Namespace, prep: Prep, paths: Sequence[str] | None = None, *,
         notes: bool = True) -> Loaded:
    """Every log of ``paths`` (default ``args.runs``) prepared as ``prep`` says on the
    workers of the options; failures, damage notes (``notes``: False on a second pass
    over logs whose notes the first said) and (unless ``-q``) progress and the workers'
    peak memory on stderr."""
    paths = [str(p) for p in (args.runs if paths is None else paths)]
    quiet = bool(getattr(args, "quiet", False))
    workers = _pool.workers_from_args(args)
    results = _pool.map_logs(functools.partial(prepare_log, prep=prep), paths, workers,
                             lost=_lost, on_done=progress("reading logs", quiet=quiet),
                             debug=prep.debug)
    failed = [r.error for r in results if r.error]
    good = [r for r in results if not r.error]
    if not good:  # nothing to go on: the last failure is the command's error
        for line in failed[:-1]:
            print(f"gyrotherm: error: {line}", file=sys.stderr)
        raise RunFileError(failed[-1])
    for r in results:
        for note in r.notes if notes else ():
            print(f"note: {note}", file=sys.stderr)
        if r.error:
            print(f"gyrotherm: error: {r.error}", file=sys.stderr)
    peak: dict[str, float] = {}
    for r in results:
        peak[r.worker] = max(peak.get(r.worker, 0.0), r.peak_rss_mb)
    if not quiet and (workers.scheduler or (workers.jobs > 1 and len(paths) > 1)):
        print(f"workers: {len(peak)}, peak RSS MB per worker: "
              + ", ".join(f"{v:.1f}" for v in sorted(peak.values())), file=sys.stderr)
    return _selected(args, good, failed, peak)


def _selected(args: argparse.Namespace, good: list[LogResult], failed: list[str],
              peak: dict[str, float]) -> Loaded:
    runs = [run for r in good for run in r.runs]
    wanted = {id(run) for run in select_devices(runs, getattr(args, "device", None))}
    reports: list[RestReport] = []
    feats: list[RunFeatures] = []
    readouts: list[RunReadout] = []
    for r in good:
        for k, run in enumerate(r.runs):
            if id(run) not in wanted:
                continue
            if r.reports and (rep := r.reports[k]) is not None:
                reports.append(rep)
            if r.features and (f := r.features[k]) is not None:
                feats.append(f)
            if r.readouts and (o := r.readouts[k]) is not None:
                readouts.append(o)
    return Loaded([run for run in runs if id(run) in wanted], reports, feats, failed, peak,
                  readouts, [r.path for r in good])


__all__ = [
    "Loaded",
    "LogResult",
    "Prep",
    "error_line",
    "load",
    "prep_from_args",
    "prepare_log",
]
