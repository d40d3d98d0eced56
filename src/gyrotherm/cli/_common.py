"""Shared CLI helpers: progress output, run loading, estimator options."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from gyrotherm.codecs import Run, read_run
from gyrotherm.codecs._candump_run import is_candump_log, run_from_candump
from gyrotherm.estimators import EstimatorConfig
from gyrotherm.readers import InputSpec, read_runs


def progress(label: str, *, quiet: bool = False) -> Callable[[int, int], None]:
    """A callback printing ``label: i/n`` on stderr: a single updating line on a
    terminal; elsewhere (a log, a pipe) one plain line when done, never ``\\r``."""
    tty = sys.stderr.isatty()

    def report(done: int, total: int) -> None:
        if quiet or not (tty or done == total):
            return
        end = "\n" if done == total else ""
        print(f"\r{label}: {done}/{total}" if tty else f"{label}: {done}/{total}", end=end,
              file=sys.stderr, flush=True)

    return report


def load_run(path: str) -> Run:
    """A run file (CSV version 1) or a ``candump -l`` log of the gyro's frames (shipped
    DBC), told apart by content: a log's first non-empty line is
    ``(<seconds>) <iface> <id>#<data>``."""
    return run_from_candump(path) if is_candump_log(path) else read_run(path)


def load_runs(paths: Sequence[str], *, quiet: bool = False,
              spec: InputSpec | None = None) -> list[Run]:
    """Every run in ``paths`` (:func:`gyrotherm.readers.read_runs`: run files, candump
    logs, delimited text, flight logs; ``spec`` = the input options, default auto),
    with a progress line."""
    report = progress("reading runs", quiet=quiet)
    runs = []
    for i, p in enumerate(paths):
        found = read_runs(p, spec=spec or InputSpec())
        for note in damage_notes(p, found):
            print(f"note: {note}", file=sys.stderr)
        runs.extend(found)
        report(i + 1, len(paths))
    return runs


def damage_notes(path: str, runs: Sequence[Run]) -> list[str]:
    """What a reader left out of ``path`` (its runs' metadata): a cut end, IMU
    instances skipped. One line each, printed whatever ``-q`` says."""
    meta = runs[0].metadata if runs else {}
    notes = []
    cut_bytes = int(meta.get("bytes_cut_at_end", "0") or 0)
    cut_messages = int(meta.get("messages_cut_at_end", "0") or 0)
    if cut_bytes or cut_messages:
        what = f"{cut_bytes} bytes of a last message" if cut_bytes else \
            f"{cut_messages} IMU message(s)"
        notes.append(f"{path}: the log is cut short ({what} unread at its end); read up to "
                     "the last whole message")
    if meta.get("instances_skipped"):
        notes.append(f"{path}: IMU instance(s) skipped, the others read: "
                     f"{meta['instances_skipped']}")
    if meta.get("fast_path_fallback"):
        notes.append(f"{path}: read by the slower library decoder, not the numpy fast path "
                     f"({meta['fast_path_fallback']})")
    return notes


def add_estimator_options(parser: argparse.ArgumentParser) -> None:
    d = EstimatorConfig()
    g = parser.add_argument_group("ΔT estimator (stored in the calibration)")
    g.add_argument("--tau-s", type=float, default=d.tau_s,
                   help=f"thermal time constant, s: ΔT = τ·dT/dt (default {d.tau_s:g})")
    g.add_argument("--temperature-noise-c", type=float, default=d.noise_c,
                   help=f"sensor noise std, °C (default {d.noise_c:g})")
    g.add_argument("--temperature-lsb-c", type=float, default=d.quantisation_c,
                   help=f"sensor resolution, °C (default {d.quantisation_c:g})")
    g.add_argument("--process-noise", type=float, default=d.process_noise_c2_per_s3,
                   help=f"jerk spectral density q, °C²/s³ (default {d.process_noise_c2_per_s3:g})")
    g.add_argument("--update-period-s", type=float, default=d.update_period_s,
                   help="feed the filter a reading at most this often, s (0 = every row)")


def estimator_from_args(args: argparse.Namespace) -> EstimatorConfig:
    return EstimatorConfig(
        tau_s=args.tau_s,
        noise_c=args.temperature_noise_c,
        quantisation_c=args.temperature_lsb_c,
        process_noise_c2_per_s3=args.process_noise,
        update_period_s=args.update_period_s,
    )
