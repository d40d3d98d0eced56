"""Command line of the socketcand server: ``python -m gyrotherm.sim._socketcand``.

:func:`main` serves one channel on ``--host``:``--port`` (127.0.0.1, port 0:
ephemeral) and prints the bound port on stdout. Without ``--frames`` it serves
until interrupted; with ``--frames N`` it waits (``--timeout-s``) for
``--clients`` clients, plays ``N``
:func:`~gyrotherm.sim._socketcand_wire.demo_frame` frames in chunks of at most
1024 (flushing after each), waits for the clients to disconnect and exits.

Exit status: 0 done; 2 bad option (:class:`gyrotherm.ConfigError`, message on
stderr); 3 too few clients within the timeout; 4 clients did not read within
the timeout. ``main`` stays importable from :mod:`gyrotherm.sim._socketcand`,
which runs it as ``__main__``.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Sequence

from gyrotherm._errors import ConfigError
from gyrotherm.sim._socketcand_wire import demo_frame


def main(argv: Sequence[str] | None = None) -> int:
    """Serve a socketcand channel; with ``--frames N`` play N demo frames, then exit."""
    from gyrotherm.sim._socketcand import SocketcandServer  # the server imports this module

    parser = argparse.ArgumentParser(
        prog="python -m gyrotherm.sim._socketcand", description=main.__doc__
    )
    parser.add_argument("--host", default="127.0.0.1", help="listen address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=0, help="TCP port (default 0: ephemeral)")
    parser.add_argument("--channel", default="vcan0", help="channel name served (default vcan0)")
    parser.add_argument("--frames", type=int, default=None, help="play N demo frames, then exit")
    parser.add_argument("--clients", type=int, default=1, help="clients to wait for (default 1)")
    parser.add_argument("--timeout-s", type=float, default=30.0, help="wait limit (default 30 s)")
    args = parser.parse_args(argv)
    try:
        server = SocketcandServer(host=args.host, port=args.port, channel=args.channel).start()
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with server:
        print(server.port, flush=True)
        if args.frames is None:
            try:
                threading.Event().wait()
            except KeyboardInterrupt:
                return 0
        if not server.wait_for_clients(args.clients, args.timeout_s):
            print(
                f"error: fewer than {args.clients} clients within {args.timeout_s} s",
                file=sys.stderr,
            )
            return 3
        chunk = min(1024, server.client_queue_frames)
        for first in range(0, args.frames, chunk):
            for index in range(first, min(first + chunk, args.frames)):
                server.send(demo_frame(index))
            if not server.flush(args.timeout_s):
                print(f"error: clients did not read within {args.timeout_s} s", file=sys.stderr)
                return 4
        server.wait_until_disconnected(args.timeout_s)
    return 0
