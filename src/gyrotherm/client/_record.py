"""``gyrotherm record``: a daemon's streams into an MCAP file (ROS 2 messages), live to
Foxglove over WebSocket, and/or republished as a ROS 2 node over Zenoh (``--ros2``,
rmw_zenoh_cpp's key expressions, liveliness tokens and attachment:
:mod:`gyrotherm.client._ros2`). At least one of ``--mcap``, ``--foxglove-port``,
``--ros2``.

Client side, like ``gyrotherm listen``: subscribes to ``gyrotherm/<vehicle>/<sensor>/*``
and writes the channels of :mod:`gyrotherm.client._channels` (sensor_msgs/Imu in rad/s,
sensor_msgs/Temperature, geometry_msgs/Vector3Stamped, the state and health as
diagnostic_msgs/DiagnosticArray: all ROS 2 CDR, so ``ros2 bag play`` takes the file;
JSON state and health only with ``--json-channels``). Header stamps: the receive clock
by default (``--stamp sensor`` for the gyro's own). It first asks the
daemon's calibration queryable for the calibration's residual noise (the
angular-velocity covariance; all zeros, "unknown", when there is none or no reply
within ``--calibration-timeout-s``). It stops after ``--duration-s``, after
``--count`` rate messages, after ``--idle-timeout-s`` without any message (the
daemon went silent: off by default, a recorder may outlive daemon restarts), or on
SIGINT/SIGTERM, finishes the file and prints a summary (``--json``: one JSON object
on stdout, ``stopped_by`` saying which).

Exit status: 0 after a clean stop with at least one message recorded, 1 when nothing
arrived or the stream went silent for ``--idle-timeout-s``, 2 on a usage or
configuration error (a ``--ros-*`` option without ``--ros2``,
a sensor, namespace or node name that is no ROS 2 name).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from gyrotherm._errors import CalibrationError, ConfigError, DecodeError
from gyrotherm._signals import stop_on_signals
from gyrotherm._zenoh import DEFAULT_CONNECT, open_session, zenoh_error_text
from gyrotherm.client._channels import STAMPS, Fanout, McapSink, Sink
from gyrotherm.client._ros import residual_variance_dps2
from gyrotherm.client._ros2 import RmwZenohSink, check_names, ros2_session_config
from gyrotherm.client._subscriber import Subscriber

ROS_NODE_NAME = "gyrotherm_bridge"
_ROS_OPTIONS = {"ros_domain_id": "--ros-domain-id", "ros_namespace": "--ros-namespace",
                "ros_node_name": "--ros-node-name"}  # fmt: skip


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="gyrotherm record",
        description="Record a gyrotherm daemon's streams as ROS 2 messages in MCAP, serve "
                    "them live to Foxglove, and/or republish them as a ROS 2 node over Zenoh "
                    "(rmw_zenoh_cpp). Give at least one of --mcap, --foxglove-port, "
                    "--ros2.")  # fmt: skip
    p.add_argument("--vehicle", required=True, help="vehicle name (key gyrotherm/<vehicle>/...)")
    p.add_argument("--sensor", required=True, help="sensor name")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                   help=f"zenoh endpoint to connect to, repeatable (default {DEFAULT_CONNECT[0]})")
    p.add_argument("--zenoh-config", default=None, metavar="JSON5",
                   help="zenoh config file used unchanged (replaces --connect; default: none)")
    p.add_argument("--mcap", default=None, metavar="FILE",
                   help="write an MCAP file (default: none)")
    p.add_argument("--foxglove-port", type=int, default=None, metavar="PORT",
                   help="serve the channels live on a Foxglove WebSocket (0: any free port; "
                   "default: no server)")
    p.add_argument("--foxglove-host", default="127.0.0.1",
                   help="address the Foxglove server binds (default 127.0.0.1, loopback)")
    p.add_argument("--ros2", action="store_true",
                   help="publish every CDR channel (Imu imu/imu_raw, Temperature "
                   "temperature/delta_t, Vector3Stamped bias, DiagnosticArray state/health) "
                   "as a ROS 2 node on rmw_zenoh_cpp's key expressions and liveliness tokens, "
                   "with an rmw_zenoh node's session (gossip to the router) on the --connect "
                   "endpoints (default: off)")
    p.add_argument("--ros-domain-id", type=int, default=None, metavar="N",
                   help="with --ros2: ROS_DOMAIN_ID, 0..232 (default 0)")
    p.add_argument("--ros-namespace", default=None, metavar="NS",
                   help="with --ros2: node namespace; topics are NS/gyrotherm/<sensor>/imu, "
                   "imu_raw, temperature (default /)")
    p.add_argument("--ros-node-name", default=None, metavar="NAME",
                   help=f"with --ros2: node name (default {ROS_NODE_NAME})")
    p.add_argument("--frame-id", default=None,
                   help="ROS header frame_id (default: the sensor name)")
    p.add_argument("--stamp", choices=STAMPS, default="receive",
                   help="clock in the ROS headers: receive (the daemon's receive time, the "
                   "system clock: what rviz, robot_localization and message filters expect) "
                   "or sensor (the gyro's own time stamps: exact sample spacing, often "
                   "seconds since power-on) (default receive)")
    p.add_argument("--json-channels", action="store_true",
                   help="also write the state and health as JSON (…/state_json, "
                   "…/health_json); such an MCAP mixes encodings and ros2 bag play "
                   "refuses it (default: off, every channel ROS 2 CDR)")
    p.add_argument("--duration-s", type=float, default=None,
                   help="stop after S seconds (default: until --count, SIGINT or SIGTERM)")
    p.add_argument("--count", type=int, default=None,
                   help="stop after N rate messages (default: no limit)")
    p.add_argument("--idle-timeout-s", type=float, default=None,
                   help="stop (exit 1) when no message at all arrived for S seconds "
                   "(default: wait until another stop)")
    p.add_argument("--calibration-timeout-s", type=float, default=2.0,
                   help="wait this long for the daemon's calibration reply (2)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output on stderr")
    p.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE",
                   help="the summary as JSON: on stdout without FILE (or '-'), else to FILE "
                   "(parent directories created) (default: a line on stderr)")
    return p  # fmt: skip


def _covariance(sub: Subscriber, timeout_s: float) -> tuple[tuple[float, float, float], str]:
    try:
        info = sub.query_calibration(timeout_s=timeout_s)
    except (TimeoutError, CalibrationError, DecodeError):
        return (0.0, 0.0, 0.0), ""
    return residual_variance_dps2(info.calibration), info.calibration_id


def record_main(argv: Sequence[str] | None = None, *,
                formatter_class: type[argparse.HelpFormatter] | None = None,
                stop: threading.Event | None = None,
                on_ready: Callable[[int | None], Any] | None = None) -> int:  # fmt: skip
    """``gyrotherm record``; ``stop`` ends it from another thread, ``on_ready`` is called
    with the Foxglove server's port (None without one) once the sinks are open and the
    first message came through the subscription (both for embedding and tests)."""
    parser = _parser()
    if formatter_class is not None:
        parser.formatter_class = formatter_class
    args = parser.parse_args(argv)
    if args.mcap is None and args.foxglove_port is None and not args.ros2:
        print("gyrotherm record: error: give at least one output: --mcap FILE, "
              "--foxglove-port PORT and/or --ros2", file=sys.stderr)  # fmt: skip
        return 2
    error = _ros_options(args) or _positive(args)
    if error:
        print(f"gyrotherm record: error: {error}", file=sys.stderr)
        return 2
    stop = threading.Event() if stop is None else stop
    with stop_on_signals(stop):
        try:
            if args.zenoh_config:
                session = open_session(config_file=args.zenoh_config)
            elif args.ros2:  # an rmw_zenoh node's session: reaches nodes behind a router
                session = _open(ros2_session_config(args.connect or DEFAULT_CONNECT))
            else:
                session = open_session(connect=args.connect or DEFAULT_CONNECT)
        except ConfigError as exc:
            print(f"gyrotherm record: error: {exc}", file=sys.stderr)
            return 2
        with session:
            return _record(args, session, stop, on_ready)


def _open(config: Any) -> Any:
    import zenoh

    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        raise ConfigError(f"cannot open zenoh session: {zenoh_error_text(exc)}") from exc


def _positive(args: argparse.Namespace) -> str | None:
    """The error text for a duration, timeout or count that is not a positive number."""
    for dest, opt in (("duration_s", "--duration-s"), ("idle_timeout_s", "--idle-timeout-s"),
                      ("calibration_timeout_s", "--calibration-timeout-s"), ("count", "--count")):
        v = getattr(args, dest)
        if v is not None and not (math.isfinite(v) and v > 0):
            return f"{opt} {v!r}: must be a positive number"
    return None


def _ros_options(args: argparse.Namespace) -> str | None:
    """Fill the ``--ros-*`` defaults; the error text when one is given without ``--ros2``
    or a name is not a ROS 2 name."""
    given = [opt for dest, opt in _ROS_OPTIONS.items() if getattr(args, dest) is not None]
    if given and not args.ros2:
        return f"{', '.join(given)} only applies with --ros2"
    args.ros_domain_id = 0 if args.ros_domain_id is None else args.ros_domain_id
    args.ros_namespace = args.ros_namespace or "/"
    args.ros_node_name = args.ros_node_name or ROS_NODE_NAME
    if args.ros2:
        try:
            import xxhash  # noqa: F401  (rmw_zenoh's GIDs; the optional `ros2` extra)
        except ImportError:
            return "--ros2 needs the xxhash package: pip install 'gyrotherm[ros2]'"
        try:
            check_names(args.sensor, domain_id=args.ros_domain_id,
                        namespace=args.ros_namespace, node_name=args.ros_node_name)
        except ValueError as exc:
            return f"--ros2: {exc}"
    return None


def _record(args: argparse.Namespace, session: Any, stop: threading.Event,
            on_ready: Callable[[int | None], Any] | None) -> int:  # fmt: skip
    with Subscriber(args.vehicle, args.sensor, session=session) as probe:
        cov, cal_id = _covariance(probe, args.calibration_timeout_s)
    sinks: list[Sink] = []
    server_port = None
    ros: RmwZenohSink | None = None
    try:  # a sink that fails to open closes those opened before it (file, server, tokens)
        if args.mcap is not None:
            sinks.append(McapSink(args.mcap))
        if args.foxglove_port is not None:
            from gyrotherm.client._foxglove import FoxgloveSink  # lazy: optional foxglove-sdk

            fox = FoxgloveSink(host=args.foxglove_host, port=args.foxglove_port)
            server_port = fox.port
            sinks.append(fox)
        if args.ros2:
            ros = RmwZenohSink(session, domain_id=args.ros_domain_id,
                               namespace=args.ros_namespace, node_name=args.ros_node_name)
            sinks.append(ros)
        fan = Fanout(sinks, sensor=args.sensor, frame_id=args.frame_id, covariance_dps2=cov,
                     stamp=args.stamp, json_channels=args.json_channels)
    except BaseException:
        for sink in reversed(sinks):
            sink.close()
        raise
    rates = threading.Semaphore(0)

    def on_rate(msg: Any) -> None:
        fan.on_rate(msg)
        rates.release()

    t0 = time.monotonic()
    try:
        with Subscriber(args.vehicle, args.sensor, session=session, on_rate=on_rate,
                        on_state=fan.on_state, on_health=fan.on_health) as sub:  # fmt: skip
            if not args.quiet:
                where = f" → {args.mcap}" if args.mcap else ""
                live = ("" if server_port is None
                        else f", Foxglove ws://{args.foxglove_host}:{server_port}")
                if ros is not None:
                    live += (f", ROS 2 node {ros.namespace.rstrip('/')}/{ros.node_name} "
                             f"domain {ros.domain_id} (rmw_zenoh)")
                print(f"gyrotherm record: {sub.keys.rate.rsplit('/', 1)[0]}/*{where}{live}",
                      file=sys.stderr)  # fmt: skip
            if on_ready is not None:  # once the subscription delivers (health: 1 Hz)
                while not (fan.first_message.wait(0.2) or stop.is_set()):
                    pass
                on_ready(server_port)
            stopped_by = _wait(stop, rates, args.count, args.duration_s,
                               args.idle_timeout_s, fan)
            stats = sub.stats()
    finally:
        fan.close()
    summary = {
        "mcap": args.mcap, "foxglove_port": server_port,
        "ros2": None if ros is None else ros.summary(), "duration_s": time.monotonic() - t0,
        "stopped_by": stopped_by,
        "calibration_id": cal_id, "angular_velocity_variance_dps2": list(cov),
        "messages": dict(sorted(fan.counts.items())),
        "rate": {"received": stats.rate.received, "gaps": stats.rate.gaps,
                 "missing": stats.rate.missing, "undecodable": stats.rate.undecodable},
    }  # fmt: skip
    if args.json == "-":
        print(json.dumps(summary))
    elif args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(summary) + "\n", encoding="utf-8")
    elif not args.quiet:
        print(f"recorded {summary['messages']} in {summary['duration_s']:.1f} s", file=sys.stderr)
    if stopped_by == "idle":
        print(f"gyrotherm record: no message for {args.idle_timeout_s:g} s: the daemon stopped "
              "publishing or the link is down (is `gyrotherm run` up?); the file is complete "
              "up to there", file=sys.stderr)
        return 1
    return 0 if fan.counts else 1


def _wait(stop: threading.Event, rates: threading.Semaphore, count: int | None,
          duration_s: float | None, idle_s: float | None = None,
          fan: Fanout | None = None) -> str:  # fmt: skip
    """Block until a stop; which one: "signal", "duration", "count" or "idle" (no
    message through ``fan`` for ``idle_s``)."""
    deadline = None if duration_s is None else time.monotonic() + duration_s
    seen = 0
    while not stop.is_set():
        now = time.monotonic()
        left = None if deadline is None else deadline - now
        if left is not None and left <= 0:
            return "duration"
        if idle_s is not None and fan is not None and now - fan.last_message_s >= idle_s:
            return "idle"
        step = 0.2 if left is None else min(0.2, left)
        if count is None:
            stop.wait(step)
        elif rates.acquire(timeout=step):
            seen += 1
            if seen >= count:
                return "count"
    return "signal"
