"""Typed subscriber to a gyrotherm daemon's rate, state and health streams.

Each zenoh sample is decoded (:mod:`gyrotherm.codecs._wire_decode`) in zenoh's callback
thread, then handed to the user's callback (``on_rate`` ...) or, without one,
queued for iteration (``for msg in sub.rates(timeout_s=1.0)``). Per stream the
subscriber keeps:

* **sequence accounting** from ``seq``: gaps, missing, duplicates and resets
  (the rules are in :mod:`gyrotherm.client._stats`).
* **latency** = subscriber wall clock at arrival (``time.time()``) − the message's
  ``receive_time_s`` (the daemon's wall clock when the CAN frame arrived), so it
  covers daemon processing + zenoh transport (both clocks are the host's wall
  clock: across hosts they must be synchronised); exact count, mean, min and max,
  reservoir-sampled p50/p99.
* counts of undecodable payloads (never raised into zenoh) and of messages the
  bounded iteration queue dropped (oldest first: a servo loop wants fresh data).
* **non-finite samples**: a rate message whose corrected, raw or bias value is NaN
  or ±inf is delivered with :attr:`StatusFlags.NON_FINITE` set (by the decoder,
  whatever the publisher) and counted in ``StreamStats.non_finite``; a servo loop
  that skips samples with ``flags`` set never feeds one to its controller.

One zenoh subscriber on ``gyrotherm/<vehicle>/<sensor>/*`` feeds all three streams
from one callback thread, so callbacks (and accounting) of different streams run in
zenoh's delivery order, which for one publishing session at one priority is the
publish order (a state published before a rate is seen first). Callbacks must be
quick: they delay every later sample. Do not call :meth:`Subscriber.close` from
inside one of its callbacks.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Generic, TypeVar

import zenoh

from gyrotherm._errors import CalibrationError, ConfigError, DecodeError
from gyrotherm._zenoh import DEFAULT_CONNECT, KeyExprs, keys, open_session
from gyrotherm.client._stats import (
    LatencyTracker,
    SequenceTracker,
    StreamStats,
    SubscriberStats,
)
from gyrotherm.codecs._wire import (
    CalibrationInfo,
    HealthMessage,
    Payload,
    RateMessage,
    StateMessage,
    StatusFlags,
)
from gyrotherm.codecs._wire_decode import (
    decode_calibration_info,
    decode_health,
    decode_rate,
    decode_state,
)

_log = logging.getLogger(__name__)
_NON_FINITE = StatusFlags.NON_FINITE
_M = TypeVar("_M", RateMessage, StateMessage, HealthMessage)


class _Stream(Generic[_M]):
    """One key expression: decode, account, then call back or queue."""

    def __init__(
        self,
        name: str,
        decode: Callable[[Payload], _M],
        callback: Callable[[_M], Any] | None,
        queue_size: int,
        clock: Callable[[], float],
        reservoir_size: int,
        activity: threading.Condition,
    ) -> None:
        self.name = name
        self._activity = activity
        self._decode: Callable[[Payload], _M] = decode
        self.callback: Callable[[_M], Any] | None = callback
        self._clock = clock
        self._cond = threading.Condition()
        self._queue: collections.deque[_M] = collections.deque(maxlen=queue_size)
        self._seq = SequenceTracker()
        self._latency = LatencyTracker(reservoir_size=reservoir_size)
        self._received = self._undecodable = self._dropped = self._callback_errors = 0
        self._non_finite = 0
        self._last_error: str | None = None
        self.closed = False

    def on_sample(self, sample: zenoh.Sample) -> None:
        now_s = self._clock()
        if self.closed or sample.kind != zenoh.SampleKind.PUT:
            return
        try:
            msg = self._decode(sample.payload.to_bytes())
        except DecodeError as exc:
            with self._cond:
                self._undecodable += 1
                self._last_error = str(exc)
            self._notify_activity()
            return
        with self._cond:
            self._received += 1
            if msg.flags & _NON_FINITE:
                self._non_finite += 1
            self._seq.observe(msg.seq)
            self._latency.add(now_s - msg.receive_time_s)
            if self.callback is None:
                if len(self._queue) == self._queue.maxlen:
                    self._dropped += 1
                self._queue.append(msg)
                self._cond.notify()
        if self.callback is not None:
            try:
                self.callback(msg)
            except Exception as exc:  # a user bug must not kill zenoh's thread
                with self._cond:
                    self._callback_errors += 1
                    self._last_error = f"{self.name} callback raised {exc!r}"
                _log.exception("gyrotherm %s callback raised", self.name)
        self._notify_activity()

    def _notify_activity(self) -> None:
        with self._activity:
            self._activity.notify_all()

    def iterate(self, timeout_s: float | None) -> Iterator[_M]:
        if self.callback is not None:  # raised here, not at the first next()
            raise ConfigError(f"{self.name} stream has an on_{self.name} callback: no iteration")
        return self._iterate(timeout_s)

    def _iterate(self, timeout_s: float | None) -> Iterator[_M]:
        while True:
            with self._cond:
                ready = self._cond.wait_for(lambda: self._queue or self.closed, timeout_s)
                if self.closed or not ready:
                    return
                msg = self._queue.popleft()
            yield msg

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()

    def stats(self) -> StreamStats:
        with self._cond:
            s = self._seq
            return StreamStats(
                self._received, s.gaps, s.missing, s.resets, s.duplicates, self._undecodable,
                self._dropped, self._callback_errors, s.last_seq, self._last_error,
                self._latency.snapshot(), self._non_finite,
            )  # fmt: skip


class Subscriber:
    """Subscribe to ``gyrotherm/<vehicle>/<sensor>/{rate,state,health}``.

    Never hands over a non-finite rate as clean: a rate message with a NaN or ±inf
    corrected, raw or bias value carries ``StatusFlags.NON_FINITE`` (bit 9) and is
    counted in ``stats().rate.non_finite``; test ``msg.flags`` before using a sample.

    Without ``session`` a peer session is opened that connects to ``connect``
    (listens nowhere, no scouting) and is closed by :meth:`close`; a given
    ``session`` is left open. ``queue_size`` bounds each iteration queue.
    ``clock`` (s, wall clock) is injectable for tests.
    """

    def __init__(
        self,
        vehicle: str,
        sensor: str,
        *,
        connect: Sequence[str] = DEFAULT_CONNECT,
        session: zenoh.Session | None = None,
        on_rate: Callable[[RateMessage], Any] | None = None,
        on_state: Callable[[StateMessage], Any] | None = None,
        on_health: Callable[[HealthMessage], Any] | None = None,
        queue_size: int = 1024,
        reservoir_size: int = 4096,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.keys: KeyExprs = keys(vehicle, sensor)
        if queue_size < 1:
            raise ConfigError(f"queue_size = {queue_size} is invalid: must be >= 1")
        self._closed = False
        self._activity = threading.Condition()
        common = (queue_size, clock, reservoir_size, self._activity)
        self._rate = _Stream("rate", decode_rate, on_rate, *common)
        self._state = _Stream("state", decode_state, on_state, *common)
        self._health = _Stream("health", decode_health, on_health, *common)
        self._owns_session = session is None
        self._session = open_session(connect=connect) if session is None else session
        self._by_key: dict[str, _Stream[Any]] = {
            self.keys.rate: self._rate,
            self.keys.state: self._state,
            self.keys.health: self._health,
        }
        self._zsubs: list[zenoh.Subscriber[None]] = []
        try:
            # One subscriber for the three keys: one callback thread, so callbacks of
            # different streams run in the order zenoh delivered the samples.
            prefix = self.keys.rate.rsplit("/", 1)[0]
            self._zsubs.append(self._session.declare_subscriber(f"{prefix}/*", self._on_sample))
        except BaseException:
            self.close()
            raise

    def _on_sample(self, sample: zenoh.Sample) -> None:
        # exact keys only: a sample on a wildcard key is never the daemon's (see
        # query_calibration)
        stream = self._by_key.get(str(sample.key_expr))
        if stream is not None:
            stream.on_sample(sample)

    @property
    def session(self) -> zenoh.Session:
        """The zenoh session in use."""
        return self._session

    def rates(self, *, timeout_s: float | None = None) -> Iterator[RateMessage]:
        """Yield rate messages as they arrive; stop when none arrives within
        ``timeout_s`` seconds (None: wait forever) or when the subscriber closes."""
        return self._rate.iterate(timeout_s)

    def states(self, *, timeout_s: float | None = None) -> Iterator[StateMessage]:
        """Yield state messages (see :meth:`rates`)."""
        return self._state.iterate(timeout_s)

    def healths(self, *, timeout_s: float | None = None) -> Iterator[HealthMessage]:
        """Yield health messages (see :meth:`rates`)."""
        return self._health.iterate(timeout_s)

    def stats(self) -> SubscriberStats:
        """Snapshot of every stream's counters and latency."""
        return SubscriberStats(self._rate.stats(), self._state.stats(), self._health.stats())

    def wait_for(
        self, predicate: Callable[[SubscriberStats], bool], *, timeout_s: float
    ) -> bool:
        """Block until ``predicate(self.stats())`` holds (re-checked after every sample,
        decoded or not, once its callback returned) or ``timeout_s`` passes; return it."""
        deadline = time.monotonic() + timeout_s
        with self._activity:
            while not predicate(self.stats()):
                remaining = deadline - time.monotonic()
                if remaining <= 0 or self._closed:
                    return False
                self._activity.wait(remaining)
        return True

    def query_calibration(self, *, timeout_s: float = 2.0) -> CalibrationInfo:
        """Ask the daemon's ``…/calibration`` queryable for its calibration and health.

        Only a reply on exactly ``…/calibration`` counts: the daemon replies on that
        key, and a reply on a wildcard key (``gyrotherm/*/…``, ``**``) passes the
        daemon's access control, which matches keys by inclusion (docs/operations.md,
        "Threat model"). Raises TimeoutError when no such reply arrives within
        ``timeout_s``, CalibrationError when only error replies came, DecodeError on
        a malformed reply.
        """
        replies = self._session.get(self.keys.calibration, timeout=timeout_s)
        error: str | None = None
        for reply in replies:
            if reply.ok is not None:
                if str(reply.ok.key_expr) == self.keys.calibration:
                    return decode_calibration_info(reply.ok.payload.to_bytes())
                continue
            err = reply.err
            error = err.payload.to_bytes().decode("utf-8", "replace") if err else "?"
        if error is not None:
            raise CalibrationError(f"{self.keys.calibration}: daemon replied with error: {error}")
        raise TimeoutError(f"{self.keys.calibration}: no reply within {timeout_s} s")

    def close(self) -> None:
        """Stop receiving (idempotent); iterators end; an owned session is closed."""
        if self._closed:
            return
        self._closed = True
        for stream in (self._rate, self._state, self._health):
            stream.close()
        with self._activity:
            self._activity.notify_all()
        for zsub in self._zsubs:
            try:
                zsub.undeclare()
            except zenoh.ZError:  # session already closed by its owner
                pass
        self._zsubs.clear()
        if self._owns_session:
            self._session.close()

    @property
    def closed(self) -> bool:
        """True once :meth:`close` ran."""
        return self._closed

    def __enter__(self) -> Subscriber:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
