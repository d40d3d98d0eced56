"""``gyrotherm listen``: live view of a daemon's streams, then a summary.

One line per update, at most ``--max-hz`` (default 10) lines a second::

    #1234 raw[+0.0110 +0.0220 +0.1000] corr[+0.0010 +0.0020 +0.0700] dps  T 25.31 C  dT +0.300 C
      flags=T_CLAMPED  gaps=1/3  lat p50=0.37 p99=4.71 ms          (one line on screen)

(``raw``/``corr``: raw and corrected rate per axis x y z, °/s; ``T``/``dT`` from the
latest state message, with ``zero pending|done[x y z]|failed`` when the daemon runs a
boot-time zero (its offsets, °/s, are part of the correction), and ``learn[status; used
N left out reason=count; T lo..hi C; held-out learnt vs in use dps; collecting]`` when it
runs ``[learn]``; ``gaps`` = gap count /
missing messages on the rate stream; latency as :class:`gyrotherm.client.Subscriber`
measures it.) It exits after ``--count`` rate messages or ``--timeout-s`` seconds,
printing per-stream totals.

It first says on stderr what it waits for (the key expressions and the endpoint),
and gives up when no message at all (rate, state or health) arrived within
``--timeout-s`` or, without it, :data:`NOTHING_TIMEOUT_S` (30 s), with a hint
(is ``gyrotherm run`` up, is the endpoint right) instead of waiting forever.

Exit status: 0 when ``--count`` was reached, or without ``--count`` when at least
one message arrived (or on Ctrl-C); 1 otherwise; 2 on a usage or configuration error.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

from gyrotherm._errors import ConfigError
from gyrotherm._zenoh import DEFAULT_CONNECT, open_session
from gyrotherm.client._stats import LatencyStats, StreamStats
from gyrotherm.client._subscriber import Subscriber
from gyrotherm.codecs._wire import (
    HealthMessage,
    LearnProgress,
    RateMessage,
    StateMessage,
    StatusFlags,
    ZeroStatus,
)

#: Without ``--timeout-s``: give up when nothing at all arrived within this long, s.
NOTHING_TIMEOUT_S = 30.0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="gyrotherm listen", description="Live view of a gyrotherm daemon's Zenoh streams."
    )
    p.add_argument("--vehicle", required=True, help="vehicle name (key gyrotherm/<vehicle>/...)")
    p.add_argument("--sensor", required=True, help="sensor name")
    p.add_argument(
        "--connect", action="append", default=None, metavar="ENDPOINT",
        help=f"zenoh endpoint to connect to, repeatable (default {DEFAULT_CONNECT[0]})",
    )  # fmt: skip
    p.add_argument("--zenoh-config", default=None, metavar="JSON5",
                   help="zenoh config file used unchanged (replaces --connect; "
                   "default: none)")
    p.add_argument("--count", type=int, default=None,
                   help="stop after N rate messages (default: run on)")
    p.add_argument("--timeout-s", type=float, default=None,
                   help="stop after S seconds (default: run on, but give up after "
                        f"{NOTHING_TIMEOUT_S:g} s when nothing at all arrived)")
    p.add_argument("--max-hz", type=float, default=10.0, help="live lines per second (default 10)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no 'waiting for' line on stderr (also accepted before 'listen')")
    return p


def _flags_text(flags: StatusFlags) -> str:
    if not flags:
        return "-"
    names = [f.name for f in StatusFlags if f and f in flags and f.name]
    unknown = int(flags) & ~sum(int(f) for f in StatusFlags)
    if unknown:
        names.append(hex(unknown))
    return "|".join(names)


def _ms(x: float) -> str:
    return "-" if math.isnan(x) else f"{x * 1e3:.2f}"


def _vec(v: tuple[float, float, float]) -> str:
    return " ".join(f"{x:+.4f}" for x in v)


def format_line(
    rate: RateMessage | None, state: StateMessage | None, rate_stats: StreamStats
) -> str:
    """One live-view line from the latest rate and state messages."""
    parts = []
    if rate is not None:
        parts.append(f"#{rate.seq} raw[{_vec(rate.raw_rate_dps)}] corr[{_vec(rate.rate_dps)}] dps")
    else:
        parts.append("# no rate yet")
    if state is not None:
        parts.append(f"T {state.temperature_c:.2f} C  dT {state.delta_t_c:+.3f} C")
        z = state.zero
        if z is not None and not (z.status == ZeroStatus.OFF and state.learn is not None):
            done = z.status == ZeroStatus.DONE
            parts.append(f"zero {z.status_name}" + (f"[{_vec(z.offset_dps)}]" if done else ""))
        if state.learn is not None:
            parts.append(learn_text(state.learn))
    flags = rate.flags if rate is not None else (state.flags if state else StatusFlags.NONE)
    lat = rate_stats.latency
    parts.append(f"flags={_flags_text(flags)}")
    parts.append(f"gaps={rate_stats.gaps}/{rate_stats.missing}")
    parts.append(f"lat p50={_ms(lat.p50_s)} p99={_ms(lat.p99_s)} ms")
    return "  ".join(parts)


def learn_text(p: LearnProgress) -> str:
    """The ``[learn]`` mode's progress: status, warm-ups, coverage, held-out errors."""
    out = f"learn[{p.status}; used {p.warmups_used}"
    if p.rejected:
        out += " left out " + ",".join(f"{k}={v}" for k, v in sorted(p.rejected.items()))
    if math.isfinite(p.t_min_c):
        out += f"; T {p.t_min_c:.1f}..{p.t_max_c:.1f} C"
    if math.isfinite(p.candidate_rms_dps):
        out += f"; held-out {p.candidate_rms_dps:.4f} vs {p.current_rms_dps:.4f} dps"
    return out + ("; collecting]" if p.collecting else "]")


def _summary_line(name: str, s: StreamStats) -> str:
    lat: LatencyStats = s.latency
    return (
        f"{name}: received={s.received} gaps={s.gaps} missing={s.missing} resets={s.resets} "
        f"duplicates={s.duplicates} undecodable={s.undecodable} dropped={s.dropped} "
        f"latency_ms mean={_ms(lat.mean_s)} p50={_ms(lat.p50_s)} p99={_ms(lat.p99_s)} "
        f"max={_ms(lat.max_s)}"
    )


class _Latest:
    """Latest state and health messages, updated from the subscriber's callbacks."""

    def __init__(self) -> None:
        self.state: StateMessage | None = None
        self.health: HealthMessage | None = None

    def on_state(self, msg: StateMessage) -> None:
        self.state = msg

    def on_health(self, msg: HealthMessage) -> None:
        self.health = msg


def _run(
    sub: Subscriber, latest: _Latest, count: int | None, timeout_s: float | None, max_hz: float
) -> int:
    """Print live lines until ``count`` rate messages or ``timeout_s``; return the count.

    Returns early when nothing at all arrived within ``timeout_s`` or
    :data:`NOTHING_TIMEOUT_S` (the caller tells the user why).
    """
    min_period_s = 1.0 / max_hz if max_hz > 0 else 0.0
    start = time.monotonic()
    deadline = None if timeout_s is None else start + timeout_s
    nothing_deadline = start + (NOTHING_TIMEOUT_S if timeout_s is None else timeout_s)
    received = 0
    last_rate: RateMessage | None = None
    last_print = -math.inf
    while count is None or received < count:
        wait_s = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
        if wait_s <= 0:
            break
        if (received == 0 and latest.state is None and latest.health is None
                and time.monotonic() >= nothing_deadline):
            break
        for msg in sub.rates(timeout_s=wait_s):
            received += 1
            last_rate = msg
            now = time.monotonic()
            if (count is not None and received >= count) or (
                deadline is not None and now >= deadline
            ):
                break
            if now - last_print >= min_period_s:
                last_print = now
                print(format_line(msg, latest.state, sub.stats().rate), flush=True)
    if last_rate is not None or latest.state is not None:
        print(format_line(last_rate, latest.state, sub.stats().rate), flush=True)
    return received


def listen_main(argv: list[str] | None = None, *, quiet: bool = False,
                formatter_class: type[argparse.HelpFormatter] | None = None) -> int:
    """Entry point of ``gyrotherm listen`` (argv without the program/sub-command name);
    ``quiet``: ``-q`` given before the subcommand; ``formatter_class``: the help's."""
    parser = _parser()
    if formatter_class is not None:
        parser.formatter_class = formatter_class
    args = parser.parse_args(argv)
    quiet = quiet or args.quiet
    if args.count is not None and args.count < 1:
        print(f"gyrotherm listen: --count = {args.count} is invalid: must be >= 1", file=sys.stderr)
        return 2
    if args.zenoh_config is not None and args.connect:
        print("gyrotherm listen: --connect and --zenoh-config exclude each other", file=sys.stderr)
        return 2
    session = None
    try:
        if args.zenoh_config is not None:
            session = open_session(config_file=args.zenoh_config)
        connect = tuple(args.connect) if args.connect else DEFAULT_CONNECT
        latest = _Latest()
        sub = Subscriber(
            args.vehicle, args.sensor, connect=connect, session=session,
            on_state=latest.on_state, on_health=latest.on_health,
        )  # fmt: skip
    except ConfigError as exc:
        print(f"gyrotherm listen: {exc}", file=sys.stderr)
        if session is not None:
            session.close()
        return 2
    received = 0
    interrupted = False
    base = sub.keys.rate.rsplit("/", 1)[0]
    via = (f"with zenoh config {args.zenoh_config}" if args.zenoh_config is not None
           else "via " + ", ".join(connect))
    wait_s = NOTHING_TIMEOUT_S if args.timeout_s is None else args.timeout_s
    if not quiet:
        print(f"gyrotherm listen: waiting for {base}/{{rate,state,health}} {via} "
              f"(giving up after {wait_s:g} s without a message; --timeout-s)",
              file=sys.stderr, flush=True)
    try:
        with sub:
            try:
                received = _run(sub, latest, args.count, args.timeout_s, args.max_hz)
            except KeyboardInterrupt:
                interrupted = True
            stats = sub.stats()
    finally:
        if session is not None:
            session.close()
    if not interrupted and not any(getattr(stats, n).received for n in ("rate", "state",
                                                                         "health")):
        print(f"gyrotherm listen: nothing from {base} in {wait_s:g} s {via}. Is the daemon "
              "up (`gyrotherm run` logs 'up:'; `systemctl status gyrotherm`), and is the "
              "endpoint right (--connect, or the daemon's [zenoh] listen)? The names "
              "(--vehicle/--sensor) must match its config. --timeout-s S waits longer.",
              file=sys.stderr, flush=True)
    print(f"summary: {base}")
    for name in ("rate", "state", "health"):
        print("  " + _summary_line(name, getattr(stats, name)))
    h = latest.health
    if h is not None:
        drops = ", ".join(f"{k}={v}" for k, v in sorted(h.drops.items())) or "none"
        print(
            f"  daemon: uptime_s={h.uptime_s:.1f} frames_received={h.frames_received} "
            f"frames_published={h.frames_published} drops: {drops} "
            f"counter_jumps={h.counter_jumps} "
            f"calibration={h.calibration_id or '-'} flags={_flags_text(h.flags)}"
        )
    if args.count is not None:
        return 0 if received >= args.count else 1
    anything = sum(getattr(stats, n).received for n in ("rate", "state", "health"))
    return 0 if interrupted or anything > 0 else 1
