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


def add_estimator_options(parser: argparse.ArgumentParser, *, auto: bool = False) -> None:
    """The estimator's options; ``auto``: each defaults to None, and with none of them
    given the command chooses the settings from the runs' readout
    (:func:`estimator_is_auto`)."""
    d = EstimatorConfig()
    g = parser.add_argument_group(
        "ΔT estimator (stored in the calibration)" + (
            "; with none of these, every setting comes from the runs' temperature readout "
            "(refresh, LSB, noise; τ from a chamber_c column, else 120 s), as 'diagnose "
            "--calibration' chooses it; with any of them, the others take the defaults shown"
            if auto else ""))

    def default(value: float) -> float | None:
        return None if auto else value

    g.add_argument("--tau-s", type=float, default=default(d.tau_s),
                   help=f"thermal time constant, s: ΔT = τ·dT/dt (default {d.tau_s:g})")
    g.add_argument("--temperature-noise-c", type=float, default=default(d.noise_c),
                   help=f"sensor noise std, °C (default {d.noise_c:g})")
    g.add_argument("--temperature-lsb-c", type=float, default=default(d.quantisation_c),
                   help=f"sensor resolution, °C (default {d.quantisation_c:g})")
    g.add_argument("--process-noise", type=float, default=default(d.process_noise_c2_per_s3),
                   help=f"jerk spectral density q, °C²/s³ (default {d.process_noise_c2_per_s3:g})")
    g.add_argument("--update-period-s", type=float, default=default(d.update_period_s),
                   help="feed the filter a reading at most this often, s (0 = every row; "
                   f"default {d.update_period_s:g})")


_ESTIMATOR_OPTIONS = {"tau_s": "tau_s", "temperature_noise_c": "noise_c",
                      "temperature_lsb_c": "quantisation_c",
                      "process_noise": "process_noise_c2_per_s3",
                      "update_period_s": "update_period_s"}
"""Option destination → :class:`EstimatorConfig` field."""


def estimator_is_auto(args: argparse.Namespace) -> bool:
    """True when the command chooses the estimator from the readout: it offers that
    (``add_estimator_options(auto=True)``) and none of the options was given."""
    return all(getattr(args, k, 0.0) is None for k in _ESTIMATOR_OPTIONS)


def estimator_from_args(args: argparse.Namespace) -> EstimatorConfig:
    """The estimator the options give (an option not given: its default)."""
    d = EstimatorConfig()
    return EstimatorConfig(**{f: getattr(d, f) if getattr(args, k) is None else getattr(args, k)
                              for k, f in _ESTIMATOR_OPTIONS.items()})
