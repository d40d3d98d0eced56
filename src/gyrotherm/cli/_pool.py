"""Per-log work spread over workers: :func:`map_logs`.

* ``--jobs N`` (default: the cores this process may run on): N local worker processes
  (:class:`concurrent.futures.ProcessPoolExecutor`), each taking one log at a time;
  ``--jobs 1`` runs every log in this process, one after the other. One log alone is
  always read in this process (a pool would only add its start-up).
* ``--dask-scheduler ADDRESS`` (``tcp://host:8786``): the logs go to an existing Dask
  distributed cluster, one task per log (``Client.map``); the workers must have this
  gyrotherm installed and see the logs at the same paths (shared storage). Dask is an
  optional dependency (``pip install 'gyrotherm[fleet]'``), imported only here and only
  with this option.

Results come back in the order of the inputs, whatever order the workers finish in.
The per-log function catches the log's own errors and returns them as its result; a
worker that dies (killed, out of memory) loses its log, which ``lost`` turns into a
failed result naming it; the other logs go on.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

from gyrotherm._errors import ConfigError

T = TypeVar("T")

EXTRA = "fleet"
"""The optional dependency group holding Dask (pyproject.toml)."""


def default_jobs() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class Workers:
    """Where the per-log work runs: ``jobs`` local processes (1 = this process), or the
    Dask cluster whose scheduler is at ``scheduler``."""

    jobs: int = 1
    scheduler: str | None = None


def add_worker_options(parser: argparse.ArgumentParser) -> None:
    """``--jobs`` and ``--dask-scheduler`` (docs/operations.md, Fleet processing)."""
    g = parser.add_argument_group(
        "workers (per-log reading and preparation; docs/operations.md)",
        "A log that fails is reported with its name and the others go on; the exit "
        "status is then 2, with the outputs of the good logs written.")
    g.add_argument("--jobs", type=int, metavar="N",
                   help="local worker processes, one log at a time each; 1 = serial in "
                   f"this process (default: the cores available, here {default_jobs()})")
    g.add_argument("--dask-scheduler", metavar="ADDRESS",
                   help="send the per-log work to this Dask distributed scheduler, e.g. "
                   f"tcp://host:8786 (needs pip install 'gyrotherm[{EXTRA}]'; the workers "
                   "need gyrotherm and the logs at the same paths) (default: local)")


def workers_from_args(args: argparse.Namespace) -> Workers:
    """The :class:`Workers` of parsed options (ConfigError on ``--jobs`` < 1)."""
    jobs = getattr(args, "jobs", None)
    if jobs is not None and jobs < 1:
        raise ConfigError(f"--jobs {jobs}: give 1 or more worker processes")
    return Workers(jobs=default_jobs() if jobs is None else jobs,
                   scheduler=getattr(args, "dask_scheduler", None))


def map_logs(fn: Callable[[str], T], paths: Sequence[str], workers: Workers, *,
             lost: Callable[[str, str], T],
             on_done: Callable[[int, int], None] | None = None,
             debug: bool = False) -> list[T]:
    """``[fn(p) for p in paths]`` on ``workers``, in the order of ``paths``. ``fn`` must
    pickle (a module-level function, or a :func:`functools.partial` of one);
    ``lost(path, why)`` is the result of a log whose worker died or whose Dask task
    failed (``debug``: the exception is raised instead); ``on_done(i, n)`` after each
    log."""
    if workers.scheduler:
        return _dask_map(fn, paths, workers.scheduler, lost, on_done, debug)
    if workers.jobs <= 1 or len(paths) <= 1:
        out = []
        for i, p in enumerate(paths):
            out.append(fn(p))
            if on_done:
                on_done(i + 1, len(paths))
        return out
    return _process_map(fn, paths, min(workers.jobs, len(paths)), lost, on_done)


def _process_map(fn: Callable[[str], T], paths: Sequence[str], jobs: int,
                 lost: Callable[[str, str], T],
                 on_done: Callable[[int, int], None] | None) -> list[T]:
    from concurrent.futures import Future, ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    results: dict[int, T] = {}
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures: dict[Future[T], int] = {pool.submit(fn, p): i for i, p in enumerate(paths)}
        for done, fut in enumerate(as_completed(futures), 1):
            i = futures[fut]
            try:
                results[i] = fut.result()
            except BrokenProcessPool as exc:
                results[i] = lost(paths[i], f"a worker process died ({exc}); out of memory?")
            if on_done:
                on_done(done, len(paths))
    return [results[i] for i in range(len(paths))]


def _dask_map(fn: Callable[[str], T], paths: Sequence[str], address: str,
              lost: Callable[[str, str], T],
              on_done: Callable[[int, int], None] | None, debug: bool) -> list[T]:
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise ConfigError(
            f"--dask-scheduler {address}: Dask is not installed ({exc.name} missing): "
            f"pip install 'gyrotherm[{EXTRA}]' (or run without --dask-scheduler: local "
            "cores, --jobs)") from None
    try:
        client = Client(address, timeout="20s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"--dask-scheduler {address}: cannot reach the scheduler: "
                          f"{exc}") from None
    results: dict[int, T] = {}
    try:
        futures = client.map(fn, list(paths), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for done, fut in enumerate(as_completed(futures, loop=client.loop), 1):
            i = index[fut.key]
            try:
                results[i] = fut.result()
            except Exception as exc:  # KilledWorker, a worker lost: this log only
                if debug:
                    raise
                results[i] = lost(paths[i], f"the Dask task failed: {type(exc).__name__}: "
                                  f"{exc}")
            if on_done:
                on_done(done, len(paths))
    finally:
        client.close()
    return [results[i] for i in range(len(paths))]


__all__ = ["EXTRA", "Workers", "add_worker_options", "default_jobs", "map_logs",
           "workers_from_args"]
