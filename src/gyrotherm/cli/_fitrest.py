"""``gyrotherm fit``: rest detection (``--rest auto|all``), one calibration per device.

* ``--rest auto`` (default) runs :func:`rest_of` on every run and masks the motion rows
  out of the fit; a run found entirely at rest gets no mask, so chamber runs fit exactly
  as with ``--rest all``. :func:`rest_of` is the one rest decision of ``fit``,
  ``evaluate``, ``diagnose`` and ``export``, with one set of thresholds
  (:func:`rest_config` from the same options).
* Runs whose metadata ``device_id`` differ (several IMUs in one log, as the readers
  write them) are fitted separately. ``--out`` names the files: a ``{device}`` in it
  is replaced by the device id (characters outside ``A-Za-z0-9._-`` become ``_``);
  without it, several devices make ``--out`` a directory holding ``<device>.json``.
  A single device keeps ``--out`` as the file to write.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError
from gyrotherm.codecs import Run
from gyrotherm.compensation import RunFeatures, RunScore
from gyrotherm.compensation._rest import RestConfig, RestReport, rest_of_run

DEVICE_KEY = "device_id"
PLACEHOLDER = "{device}"


def add_rest_options(parser: argparse.ArgumentParser, *, use: str = "fit",
                     auto: str | None = None) -> None:
    """``--rest`` and its tuning options; ``use`` says what the rest rows feed
    ("fit", "score"), ``auto`` overrides the help of ``--rest auto``."""
    d = RestConfig()
    g = parser.add_argument_group("rest detection (logs with motion)")
    g.add_argument("--rest", choices=("auto", "all"), default="auto",
                   help=(auto or f"auto: {use} only rows detected at rest (physical limits: "
                         "rate, armed state, logging gaps; rate variance, high-pass rate, "
                         "accelerometer)") + "; all: every row (default auto)")
    g.add_argument("--rest-threshold", type=float, default=d.threshold,
                   help=f"robust z-score above which a window is motion (default {d.threshold:g})")
    g.add_argument("--rest-window-s", type=float, default=d.window_s,
                   help=f"window length, s (default {d.window_s:g})")
    g.add_argument("--rest-min-segment-s", type=float, default=d.min_segment_s,
                   help=f"shortest rest stretch kept, s (default {d.min_segment_s:g}; a log "
                   f"covering less than {d.min_segment_s / d.min_segment_fraction:g} s needs "
                   f"{d.min_segment_fraction:g} of its time)")
    g.add_argument("--rest-max-rate-dps", type=float, default=d.max_rate_dps,
                   help="rate magnitude above which a row is motion whatever else it "
                   f"shows, °/s (default {d.max_rate_dps:g}; raise it for a gyro whose bias "
                   "is larger)")


def rest_config(args: argparse.Namespace) -> RestConfig:
    """The thresholds from the options of :func:`add_rest_options` (defaults for a
    command without them)."""
    d = RestConfig()
    return RestConfig(window_s=getattr(args, "rest_window_s", d.window_s),
                      threshold=getattr(args, "rest_threshold", d.threshold),
                      min_segment_s=getattr(args, "rest_min_segment_s", d.min_segment_s),
                      max_rate_dps=getattr(args, "rest_max_rate_dps", d.max_rate_dps))


def rest_of(run: Run, config: RestConfig | None = None) -> RestReport:
    """The rest decision of every command: a run too short for the statistical tests
    keeps the rows within the physical limits, with a note."""
    return rest_of_run(run, config or RestConfig(), short="keep")


def rest_reports(args: argparse.Namespace, runs: Sequence[Run]) -> list[RestReport]:
    """Rest detection on every run (``--rest auto``; none with ``--rest all``)."""
    if args.rest == "all":
        return []
    config = rest_config(args)
    return [rest_of(r, config) for r in runs]


def mask_motion(feats: Sequence[RunFeatures],
                reports: Sequence[RestReport]) -> list[RunFeatures]:
    """Features with the motion rows of :func:`rest_reports` masked (as given without)."""
    if not reports:
        return list(feats)
    return [f if rep.rest.all() else replace(f, rest=rep.rest)
            for f, rep in zip(feats, reports, strict=True)]


def print_rest_report(reports: Sequence[RestReport], *, file: Any = None,
                      use: str = "the fit") -> None:
    if not reports:
        return
    for rep in reports:
        if rep.note:
            print(f"Rest detection: {rep.run}: {rep.note}", file=file)
    if not any(rep.segments for rep in reports):
        n = sum(1 for rep in reports if rep.tested)
        if n:
            print(f"Rest detection: every row at rest ({n} run{'s' if n > 1 else ''})",
                  file=file)
        print(file=file)
        return
    print(f"Rest detection (rows excluded from {use}):", file=file)
    for rep in reports:
        gaps = f", {rep.gaps} logging gap{'s' if rep.gaps > 1 else ''}" if rep.gaps else ""
        print(f"  {rep.run}: {len(rep.segments)} segments, {rep.excluded_s:.1f} of "
              f"{rep.total_s:.1f} s ({100 * rep.excluded_fraction:.2f} %){gaps}", file=file)
        for s in rep.segments:
            print(f"    {s.start_s:10.2f} – {s.end_s:10.2f} s: {', '.join(s.reasons)}",
                  file=file)
    print(file=file)


def refuse_motion(reports: Sequence[RestReport], *, command: str) -> None:
    """``--rest auto`` for commands that need every row (the diagnosis, ``fit
    --effects``): a ConfigError naming each run with rows left out, its first segments
    and why (the reasons ``fit`` and ``evaluate`` print for the same rows)."""
    moving = [rep for rep in reports if rep.segments]
    if not moving:
        return
    lines = []
    for rep in moving:
        spans = ", ".join(f"{s.start_s:.1f}–{s.end_s:.1f} s: {'/'.join(s.reasons)}"
                          for s in rep.segments[:3])
        more = f" and {len(rep.segments) - 3} more" if len(rep.segments) > 3 else ""
        lines.append(f"{rep.run}: {len(rep.segments)} segments not at rest ({spans}{more}), "
                     f"{rep.excluded_s:.1f} of {rep.total_s:.1f} s")
    raise ConfigError(
        f"{command} needs the gyro at rest over whole runs (the effects' state runs "
        "through every row), and rest detection left rows out of "
        f"{len(moving)} of {len(reports)} runs: " + "; ".join(lines) + ". Fit the paper "
        "model on the rest rows with `gyrotherm fit` (--rest auto), or pass --rest all "
        "if the gyro was in fact still (a vibrating bench) to use every row")


def device_groups(runs: Sequence[Run],
                  feats: Sequence[RunFeatures]) -> dict[str, list[RunFeatures]]:
    """Features grouped by the runs' metadata ``device_id`` ("" when absent), in order."""
    groups: dict[str, list[RunFeatures]] = {}
    for run, f in zip(runs, feats, strict=True):
        groups.setdefault(run.metadata.get(DEVICE_KEY, ""), []).append(f)
    return groups


def scored_at_rest(scores: list[RunScore], args: argparse.Namespace) -> list[RunScore]:
    """The scores with rows in them; a note for runs left without any (every row
    excluded as motion); CalibrationError when nothing is left to score."""
    empty = sorted({s.run for s in scores if s.raw.n == 0})
    kept = [s for s in scores if s.raw.n > 0]
    if not kept:
        raise CalibrationError(
            f"{', '.join(args.runs)}: nothing to score with {args.calibration}: no row "
            f"of any run is at rest (--rest {args.rest}); give runs with the gyro still, "
            "or --rest all if it was still throughout")
    if empty:
        print(f"not scored (no row at rest): {', '.join(empty)}", file=sys.stderr)
    return kept


def drop_restless(feats: list[RunFeatures], *, file: Any = None) -> list[RunFeatures]:
    """``feats`` less the runs with no row at rest (a note for each): they cannot be
    fitted alone nor scored left out. All of them when every run is such (the quality
    gate ``rows`` then refuses the device, naming the count)."""
    restless = [f.rest is not None and not f.rest.any() for f in feats]
    if all(restless):
        return feats
    for f, gone in zip(feats, restless, strict=True):
        if gone:
            print(f"Rest detection: {f.name}: no row at rest, left out of the fit", file=file)
    return [f for f, gone in zip(feats, restless, strict=True) if not gone]


def safe_device_name(device: str) -> str:
    """A file name from a device id or run name: every character outside
    ``A-Za-z0-9._-`` becomes ``_`` (glob-safe: ``IMU[0]`` → ``IMU_0_``)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", device) or "device"


def run_file_stem(run_name: str) -> str:
    """``import``'s file name for a run: ``<file stem>-<device>``, the device part
    made safe as ``fit`` makes it (``log:IMU[0]`` → ``log-IMU_0_``)."""
    return safe_device_name(run_name.replace(":", "-"))


def calibration_path(out: str, device: str, n_devices: int) -> Path:
    """Where the calibration of ``device`` goes (module docstring)."""
    if PLACEHOLDER in out:
        return Path(out.replace(PLACEHOLDER, safe_device_name(device)))
    if n_devices == 1:
        return Path(out)
    if out.endswith(".json"):
        raise ConfigError(f"--out {out!r}: the runs hold {n_devices} devices; give a "
                          f"directory or a name with {PLACEHOLDER} (e.g. cal-{PLACEHOLDER}.json)")
    return Path(out) / f"{safe_device_name(device)}.json"


