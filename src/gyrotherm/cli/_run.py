"""``gyrotherm run --config FILE``: the streaming daemon."""

from __future__ import annotations

import argparse
import logging
import sys


def cmd_run(args: argparse.Namespace) -> int:
    from gyrotherm.daemon import Daemon, load_config  # only `run` loads the daemon and zenoh

    level = args.log_level or ("warning" if getattr(args, "quiet", False) else "info")
    logging.basicConfig(
        level=getattr(logging, level.upper()),
        stream=sys.stderr,
        format="%(levelname)s %(name)s: %(message)s",  # the journal adds the time
    )
    config = load_config(args.config)
    daemon = Daemon(config)
    daemon.install_signal_handlers()
    summary = daemon.run()
    dropped = sum(summary.drops.values())
    print(f"frames in {summary.frames_received}, published {summary.frames_published}, "
          f"dropped {dropped} {dict(sorted(summary.drops.items()))}", flush=True)
    return 0


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("run", help="run the streaming daemon (CAN → compensation → Zenoh)")
    p.add_argument("--config", required=True, help="TOML config file (see docs/operations.md)")
    p.add_argument("--log-level", default=None, choices=("debug", "info", "warning", "error"),
                   help="log level on stderr (default: info; with -q: warning)")
    p.set_defaults(func=cmd_run)
