"""SIGTERM/SIGINT → a ``threading.Event``, safely, for the client-side commands
(``sim stream``, ``record``). The daemon keeps plain flags instead (daemon/_service.py).

A signal handler runs in the main thread between two bytecodes, possibly while that
thread holds the lock of the very event inside ``Event.wait()``; ``Event.set()`` in the
handler would then wait for that lock forever. The handler therefore sets the event
from a short-lived thread.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType

Handler = Callable[[int, FrameType | None], None]


def stop_handler(stop: threading.Event, seen: list[int] | None = None) -> Handler:
    """A handler that records the signal in ``seen`` and sets ``stop`` from a thread."""

    def handler(signum: int, frame: FrameType | None) -> None:
        if seen is not None:
            seen.append(signum)
        threading.Thread(target=stop.set, name="stop-on-signal", daemon=True).start()

    return handler


@contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[list[int]]:
    """SIGTERM and SIGINT set ``stop`` while in the block (main thread only; elsewhere
    nothing is installed); yields the signals seen; the previous handlers come back."""
    seen: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield seen
        return
    handler = stop_handler(stop, seen)
    previous = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield seen
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
