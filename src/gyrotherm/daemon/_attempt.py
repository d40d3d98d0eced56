"""Blocking opens (the CAN bus, the Zenoh session) that SIGTERM can interrupt.

An open may block for as long as its peer likes: a socketcand server that
accepts TCP and never says ``< hi >``, a Zenoh client waiting for its router. The
daemon therefore runs each open as an :class:`Attempt` on a worker thread and
waits on :class:`threading.Event`\\ s only, looking at the stop request between
waits of at most :data:`STOP_POLL_S`, so a signal is honoured within one
:data:`STOP_POLL_S` whatever the peer does. An attempt given up on
(:meth:`Attempt.abandon`) is left to finish on its thread; whatever it opens
after that is closed at once.

Retries wait :class:`Backoff` delays: 0.1 s, doubling, capped. At exit the Zenoh
session is closed on a worker thread too, waited for at most
:data:`SESSION_CLOSE_WAIT_S` (a frozen peer makes zenoh wait 10 s).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Generic, TypeVar

import zenoh

from gyrotherm._errors import GyrothermError
from gyrotherm._zenoh import zenoh_error_text

T = TypeVar("T")
log = logging.getLogger("gyrotherm.daemon")

#: Longest a wait goes without looking at the stop event, s.
STOP_POLL_S = 0.05
#: First retry delay and cap, s.
BACKOFF_FIRST_S = 0.1
BACKOFF_CAP_S = 2.0


class Backoff:
    """Retry delays: ``first_s``, doubling, at most ``cap_s``; :meth:`reset` starts over."""

    def __init__(self, first_s: float = BACKOFF_FIRST_S, cap_s: float = BACKOFF_CAP_S) -> None:
        self._first_s = first_s
        self._cap_s = cap_s
        self._next_s = first_s

    def next_s(self) -> float:
        delay = self._next_s
        self._next_s = min(self._next_s * 2.0, self._cap_s)
        return delay

    def reset(self) -> None:
        self._next_s = self._first_s


class Attempt(Generic[T]):
    """Run ``open_fn`` once on a daemon thread; ``close_fn`` disposes of a late result."""

    def __init__(self, open_fn: Callable[[], T], close_fn: Callable[[T], object],
                 name: str) -> None:
        self.done = threading.Event()
        self.started_s = time.monotonic()
        self._open_fn = open_fn
        self._close_fn = close_fn
        self._lock = threading.Lock()
        self._abandoned = False
        self._result: T | None = None
        self.error: BaseException | None = None
        threading.Thread(target=self._run, name=name, daemon=True).start()

    def _run(self) -> None:
        try:
            result = self._open_fn()
        except BaseException as exc:  # reported to the waiting thread
            self.error = exc
            self.done.set()
            return
        with self._lock:
            abandoned = self._abandoned
            if not abandoned:
                self._result = result
        if abandoned:
            self._close_fn(result)
        self.done.set()

    def result(self) -> T:
        """The opened object (after :attr:`done`); raises what ``open_fn`` raised."""
        if self.error is not None:
            raise self.error
        assert self._result is not None
        return self._result

    def abandon(self) -> None:
        """Give up on the attempt: a result that arrives later is closed."""
        with self._lock:
            self._abandoned = True
            result, self._result = self._result, None
        if result is not None:
            self._close_fn(result)


def wait_for(done: threading.Event, stopping: Callable[[], bool], timeout_s: float) -> bool:
    """Wait until ``done`` (True), ``stopping()`` or ``timeout_s`` passed (False).

    Event waits only, at most :data:`STOP_POLL_S` each, so a stop request (a flag
    a signal handler sets; handlers must not take locks) is seen within that time.
    """
    deadline = time.monotonic() + timeout_s
    while not done.is_set() and not stopping():
        left = deadline - time.monotonic()
        if left <= 0:
            break
        done.wait(min(left, STOP_POLL_S))
    return done.is_set()


def open_session(zconf: zenoh.Config, stopping: Callable[[], bool]) -> zenoh.Session | None:
    """zenoh.open on a worker thread (a client may wait for its router); None on a stop."""
    attempt = Attempt(lambda: zenoh.open(zconf), lambda s: s.close(), "gyrotherm-zenoh-open")
    if not wait_for(attempt.done, stopping, math.inf):
        attempt.abandon()
        return None
    try:
        return attempt.result()
    except zenoh.ZError as exc:
        raise GyrothermError(f"cannot open zenoh session: {zenoh_error_text(exc)}") from exc


#: Longest the daemon waits for the Zenoh session to close at exit, s (zenoh's own
#: bound is 10 s; a frozen peer makes it wait that long).
SESSION_CLOSE_WAIT_S = 2.0


def close_session(session: zenoh.Session) -> None:
    """session.close() on a worker thread, waited for at most SESSION_CLOSE_WAIT_S."""

    def close() -> None:
        try:
            session.close()
        except zenoh.ZError as exc:
            log.warning("zenoh session close: %s", zenoh_error_text(exc))
        finally:
            done.set()

    done = threading.Event()
    threading.Thread(target=close, name="gyrotherm-zenoh-close", daemon=True).start()
    if not done.wait(SESSION_CLOSE_WAIT_S):
        log.warning("zenoh session still closing after %g s (a frozen peer?): not waiting",
                    SESSION_CLOSE_WAIT_S)
