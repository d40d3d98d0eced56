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
The per-log function catches the log's own errors and returns them as its result. A
worker that dies (killed, out of memory) loses only the log that killed it, which
``lost`` turns into a failed result naming it; the other logs go on (a local pool runs
the logs the dead worker broke again one at a time; Dask retries a task on another
worker and gives up on it after the cluster's ``allowed-failures``).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from gyrotherm._errors import ConfigError

T = TypeVar("T")

WORKER_WAIT_S = 60.0
"""How long ``--dask-scheduler`` waits for the cluster's first worker."""
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
    """A process pool; when a worker dies the pool is broken and every log it had not
    finished fails with it, so those logs are run again one at a time, each in a pool of
    its own: only the log that kills its worker again is lost."""
    from concurrent.futures import Future, ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    results: dict[int, T] = {}
    again: list[int] = []

    def done_one() -> None:
        if on_done:
            on_done(len(results), len(paths))

    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures: dict[Future[T], int] = {pool.submit(fn, p): i for i, p in enumerate(paths)}
        for fut in as_completed(futures):
            try:
                results[futures[fut]] = fut.result()
                done_one()
            except BrokenProcessPool:
                again.append(futures[fut])
    for i in sorted(again):
        with ProcessPoolExecutor(max_workers=1) as alone:
            try:
                results[i] = alone.submit(fn, paths[i]).result()
            except BrokenProcessPool as exc:
                results[i] = lost(paths[i], f"its worker process died ({exc}; out of "
                                  "memory? killed?)")
        done_one()
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
        _check_workers(client, address)
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


def _check_workers(client: Any, address: str) -> None:
    """ConfigError when the cluster has no worker within :data:`WORKER_WAIT_S`; a note
    when its workers run several tasks at once (each holds a log: memory per worker)."""
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except TimeoutError:
        raise ConfigError(f"--dask-scheduler {address}: the cluster has no worker (waited "
                          f"{WORKER_WAIT_S:g} s): start some, `dask worker {address} "
                          "--nthreads 1`") from None
    workers = client.scheduler_info().get("workers", {})
    threads = max((int(w.get("nthreads", 1)) for w in workers.values()), default=1)
    if threads > 1:
        print(f"note: --dask-scheduler {address}: workers run {threads} tasks at once, so "
              f"each holds up to {threads} logs in memory (start them with --nthreads 1 "
              "for one)", file=sys.stderr)


__all__ = ["EXTRA", "Workers", "add_worker_options", "default_jobs", "map_logs",
           "workers_from_args"]
