"""``gyrotherm sim stream``: play a simulated gyro, a run file or a candump log onto a CAN bus.

Source (one of; default ``--chamber 60``): ``--chamber HEATING_MIN`` simulates
Tang et al.'s chamber run (``--seed``, ``--rate-hz``, ``--hold-s``; ``--gyros N``:
N gyros side by side, gyro k with its own bias coefficients, seed ``seed + k`` and
CAN ids 0x120 + 2k / 0x121 + 2k, see :mod:`gyrotherm.sim._gyros`), ``--run FILE``
plays a run file, ``--candump FILE`` replays a ``candump -l`` log with its own
timestamps. Frames carry sensor time (run ``time_s``), at any ``--speed``.

Bus (``--interface``):

* ``socketcand-server`` (default; ``socketcand`` is an alias): serve the
  socketcand protocol on ``--host`` (127.0.0.1) ``--port`` (29536; 0 picks a
  free port) for ``--channel``; print ``listening on HOST:PORT channel CHANNEL``
  (flushed, so a parent process can read the port), wait for ``--wait-clients``
  clients (default 1) for up to ``--wait-timeout-s`` (default: forever), play,
  wait until the clients' queues are written, exit.
* ``socketcan`` / ``virtual``: python-can bus ``--channel`` via ``open_bus``.
* ``none``: no bus (with ``--write-candump``: just write the log).

``--write-candump FILE`` also writes every frame sent to a candump log.
SIGTERM and SIGINT stop playback cleanly. The last stdout line is a
``summary: key=value ...`` line. Exit status: 0 played or stopped by a signal;
2 bad option, unreadable input or bus that cannot be opened; 3 fewer than
``--wait-clients`` clients within ``--wait-timeout-s``.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from gyrotherm._errors import ConfigError, GyrothermError
from gyrotherm._signals import stop_on_signals
from gyrotherm.bus import FrameSink, open_bus
from gyrotherm.codecs import DEFAULT_DBC_PATH, FrameEncoder, read_run

if TYPE_CHECKING:  # the simulator is imported when the command runs, not when registered
    from gyrotherm.sim._socketcand import SocketcandServer
    from gyrotherm.sim._stream import FrameStream, PlayStats

INTERFACES = ("socketcand-server", "socketcand", "socketcan", "virtual", "none")
DEFAULT_HOST, DEFAULT_PORT, DEFAULT_HEATING_MIN = "127.0.0.1", 29536, 60.0
FLUSH_TIMEOUT_S = 10.0  # for clients to take what was sent, at the end and every 4096 frames
STOP_FLUSH_TIMEOUT_S = 2.0  # the same after SIGTERM (the units allow 10 s to stop)
_PROGRESS_INTERVAL_S = 60.0  # stderr status line period (the journal, for the units)
_WAIT_POLL_S = 0.2


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``gyrotherm sim stream`` (see the module docstring)."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--chamber", type=float, metavar="HEATING_MIN",
                     help=f"simulate a chamber run heating over this many minutes "
                     f"(default {DEFAULT_HEATING_MIN:g})")
    src.add_argument("--run", metavar="FILE", help="play a run file (CSV version 1; default: none)")
    src.add_argument("--candump", metavar="FILE", help="replay a candump -l log (default: none)")
    p.add_argument("--seed", type=int, default=0, help="--chamber: random seed (default 0)")
    p.add_argument("--gyros", type=int, default=1,
                   help="--chamber: simulated gyros on the bus, each with its own physics, "
                   "seed (seed + k) and CAN ids (DBC ids + 2k) (default 1)")
    p.add_argument("--rate-hz", type=float, default=10.0,
                   help="--chamber: sample rate, Hz (default 10)")
    p.add_argument("--hold-s", type=float, default=3600.0,
                   help="--chamber: hold before and after the ramp, s (default 3600)")
    p.add_argument("--temperature-period-s", type=float, default=None,
                   help="temperature frame period, s (default: run metadata, else 0.1)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="1 = real time, 10 = ten times faster, 0 or inf = as fast as possible")
    p.add_argument("--max-frames", type=int, default=None,
                   help="stop after N frames (default: all)")
    p.add_argument("--interface", choices=INTERFACES, default="socketcand-server",
                   help="bus to play onto (default socketcand-server; socketcand = the same)")
    p.add_argument("--channel", default="vcan0", help="CAN channel (default vcan0)")
    p.add_argument("--host", default=None,
                   help=f"socketcand-server: listen address (default {DEFAULT_HOST})")
    p.add_argument("--port", type=int, default=None,
                   help=f"socketcand-server: TCP port, 0 = any free (default {DEFAULT_PORT})")
    p.add_argument("--wait-clients", type=int, default=1,
                   help="socketcand-server: clients to wait for before playing (default 1)")
    p.add_argument("--wait-timeout-s", type=float, default=math.inf,
                   help="socketcand-server: give up waiting after S s (default: never)")
    p.add_argument("--dbc", default=str(DEFAULT_DBC_PATH),
                   help="CAN database (default: the shipped gyro.dbc)")
    p.add_argument("--write-candump", metavar="FILE",
                   help="also write the frames to a candump log FILE (default: none)")


_Subparsers = argparse._SubParsersAction  # the type of ``add_subparsers()``'s result


def register(sim_sub: _Subparsers[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    """Add ``stream`` to the ``gyrotherm sim`` subcommands; returns its parser."""
    p = sim_sub.add_parser("stream", help="play a simulated gyro onto a CAN bus",
                           description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(p)
    p.set_defaults(func=cmd_stream)
    return p


def _check(args: argparse.Namespace) -> None:
    if not args.speed >= 0:
        raise ConfigError(
            f"--speed: must be >= 0 (0 or inf: as fast as possible), got {args.speed}"
        )
    if not 1 <= args.gyros <= 16:
        raise ConfigError(f"--gyros: must be in [1, 16], got {args.gyros}")
    if args.gyros > 1 and (args.run is not None or args.candump is not None):
        raise ConfigError("--gyros: only with --chamber (simulated gyros)")
    if args.max_frames is not None and args.max_frames < 1:
        raise ConfigError(f"--max-frames: must be >= 1, got {args.max_frames}")
    if args.wait_clients < 0:
        raise ConfigError(f"--wait-clients: must be >= 0, got {args.wait_clients}")
    if not args.wait_timeout_s >= 0:
        raise ConfigError(f"--wait-timeout-s: must be >= 0, got {args.wait_timeout_s}")
    if not _serves(args):
        for name in ("host", "port"):
            if getattr(args, name) is not None:
                raise ConfigError(f"--{name}: only --interface socketcand-server takes it "
                                  f"(got --interface {args.interface})")
    if args.interface == "none" and args.write_candump is None:
        raise ConfigError("--interface none: nothing to play onto; add --write-candump FILE")


def _serves(args: argparse.Namespace) -> bool:
    return str(args.interface) in ("socketcand-server", "socketcand")


def _frames(args: argparse.Namespace) -> FrameStream:
    from gyrotherm.sim._experiment import chamber_runs
    from gyrotherm.sim._stream import frames_from_candump, frames_from_run

    if args.candump is not None:
        return frames_from_candump(args.candump, dbc_path=args.dbc)
    encoder = FrameEncoder(args.dbc)
    if args.run is not None:
        run = read_run(args.run)
    else:
        minutes = DEFAULT_HEATING_MIN if args.chamber is None else args.chamber
        if not 0 <= minutes <= 24 * 60:
            raise ConfigError(f"--chamber: heating time must be in [0, 1440] min, got {minutes}")
        if args.gyros > 1:
            from gyrotherm.sim._gyros import gyro_params, several_gyros

            runs = [chamber_runs([minutes], seed=args.seed + k, rate_hz=args.rate_hz,
                                 hold_s=args.hold_s, gyro=gyro_params(k))[0]
                    for k in range(args.gyros)]
            return several_gyros(runs, dbc_path=args.dbc,
                                 temperature_period_s=args.temperature_period_s)
        run = chamber_runs([minutes], seed=args.seed, rate_hz=args.rate_hz, hold_s=args.hold_s)[0]
    return frames_from_run(run, encoder=encoder, temperature_period_s=args.temperature_period_s)


def _wait_for_clients(server: SocketcandServer, n: int, timeout_s: float,
                      stop: threading.Event) -> bool:
    waited = 0.0
    while not stop.is_set():
        step = min(_WAIT_POLL_S, timeout_s - waited)
        if server.wait_for_clients(n, step):
            return True
        waited += step
        if waited >= timeout_s:
            return False
    return False


def _summary(stats: PlayStats, extra: dict[str, object]) -> str:
    fields: dict[str, object] = {
        "frames_sent": stats.frames_sent,
        "rate_frames": stats.rate_frames,
        "temperature_frames": stats.temperature_frames,
        "other_frames": stats.other_frames,
        "saturated": stats.saturated,
        "sensor_span_s": f"{stats.sensor_span_s:.3f}",
        "wall_s": f"{stats.duration_s:.3f}",
        "frames_per_s": f"{stats.frames_per_s:.0f}" if stats.duration_s > 0 else "-",
        "stopped": "yes" if stats.stopped else "no",
        **extra,
    }
    return "summary: " + " ".join(f"{k}={v}" for k, v in fields.items())


def cmd_stream(args: argparse.Namespace) -> int:
    """Run ``gyrotherm sim stream`` (see the module docstring); returns the exit status."""
    from gyrotherm.sim._socketcand import SocketcandServer
    from gyrotherm.sim._stream import CandumpSink, FlushingSink, TeeSink, play

    _check(args)
    quiet = bool(getattr(args, "quiet", False))
    frames = _frames(args)
    stop = threading.Event()
    sinks: list[FrameSink] = []
    server: SocketcandServer | None = None
    extra: dict[str, object] = {}
    with stop_on_signals(stop) as signals:
        try:
            if args.write_candump is not None:
                Path(args.write_candump).parent.mkdir(parents=True, exist_ok=True)
                sinks.append(CandumpSink(args.write_candump, channel=args.channel))
                extra["candump"] = args.write_candump
            if _serves(args):
                host = DEFAULT_HOST if args.host is None else args.host
                port = DEFAULT_PORT if args.port is None else args.port
                server = SocketcandServer(host=host, port=port, channel=args.channel).start()
                bound_host, bound_port = server.address
                shown = f"[{bound_host}]" if ":" in bound_host else bound_host
                print(f"listening on {shown}:{bound_port} channel {args.channel}", flush=True)
                sinks.append(FlushingSink(server, timeout_s=FLUSH_TIMEOUT_S))
            elif args.interface != "none":
                sinks.append(open_bus(interface=args.interface, channel=args.channel))
            if server is not None and args.wait_clients > 0:
                if not _wait_for_clients(server, args.wait_clients, args.wait_timeout_s, stop):
                    if not stop.is_set():
                        print(f"gyrotherm: error: fewer than {args.wait_clients} socketcand "
                              f"clients within {args.wait_timeout_s:g} s", file=sys.stderr)
                        return 3
            sink = sinks[0] if len(sinks) == 1 else TeeSink(*sinks)

            def report(sent: int) -> None:
                if not quiet:
                    print(f"sim stream: {sent} frames sent", file=sys.stderr, flush=True)

            stats = play(frames, sink, speed=args.speed, stop=stop, progress=report,
                         progress_interval_s=_PROGRESS_INTERVAL_S, max_frames=args.max_frames)
            if server is not None:
                flushed = server.flush(STOP_FLUSH_TIMEOUT_S if stats.stopped else FLUSH_TIMEOUT_S)
                clients = server.client_stats()
                extra["clients"] = len(clients)
                extra["dropped"] = sum(c.frames_dropped for c in clients)
                extra["flushed"] = "yes" if flushed else "no"
        finally:
            for s in reversed(sinks):
                s.shutdown()
    if signals:
        extra["signal"] = signal.Signals(signals[0]).name
    print(_summary(stats, extra), flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Standalone entry point: ``python -m gyrotherm.cli._stream [options]``."""
    parser = argparse.ArgumentParser(prog="gyrotherm sim stream", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return cmd_stream(args)
    except GyrothermError as exc:
        print(f"gyrotherm: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["INTERFACES", "add_arguments", "cmd_stream", "main", "register"]
