"""``evaluate --zero [--zero-options ...]``: the daemon's boot-time zero offline
(docs/model.md §10)."""

from __future__ import annotations

import argparse
import math
from typing import Any

from gyrotherm._errors import ConfigError
from gyrotherm.compensation import RunFeatures, ZeroConfig, ZeroSeries


def add_zero_option(parser: argparse.ArgumentParser) -> None:
    """``--zero`` and ``--zero-options KEY=VALUE,...`` (which implies ``--zero``). Two
    options, not one with an optional value: ``evaluate CAL --zero RUN`` must not take
    RUN for the settings."""
    parser.add_argument(
        "--zero", action="store_true",
        help="apply the daemon's boot-time zero from each run's first row (docs/model.md "
             "\"Boot-time zero\") with the [zero] defaults (default: no zero)")
    parser.add_argument(
        "--zero-options", metavar="KEY=VALUE,...",
        help="the zero with these [zero] keys changed, e.g. window_s=60,settle_s=30 "
             "(implies --zero; default: the daemon's defaults)")


def zero_option(args: argparse.Namespace) -> ZeroConfig | None:
    """None without ``--zero``/``--zero-options``; else ZeroConfig (defaults + overrides)."""
    spec: str | None = args.zero_options
    if spec is None:
        return ZeroConfig() if args.zero else None
    items: dict[str, float] = {}
    for part in filter(None, (p.strip() for p in spec.split(","))):
        key, eq, value = part.partition("=")
        try:
            if not eq:
                raise ValueError
            items[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--zero-options: {part!r} is not KEY=NUMBER (keys: "
                              f"{', '.join(ZeroConfig().to_dict())})") from None
    return ZeroConfig.from_dict(items, where="--zero-options")


def zero_report(f: RunFeatures, z: ZeroSeries) -> dict[str, Any]:
    """One run's zero for ``--json``: status, sensor time it was taken (s), z (°/s)."""
    return {"run": f.name, "status": z.status.name.lower(),
            "done_s": None if math.isnan(z.done_s) else z.done_s,
            "offset_dps": {a: float(v[-1]) if len(v) else 0.0 for a, v in z.offset_dps.items()},
            "windows_rejected": z.windows_rejected}
