"""gyrotherm._signals: SIGTERM/SIGINT set a stop event without deadlocking on it."""

from __future__ import annotations

import subprocess
import sys

TIMEOUT_S = 60.0


def test_the_signal_handler_cannot_deadlock_on_the_stop_event() -> None:
    """The handler runs in the main thread, maybe while ``stop.wait()`` holds the event's
    lock there (``stop.set()`` in the handler then never returns): it must return without
    that lock, and ``stop`` be set once the lock is free. In a process of its own, so that
    a deadlock fails by timeout instead of hanging the suite."""
    code = ("import signal, threading\n"
            "from gyrotherm._signals import stop_handler\n"
            "stop = threading.Event()\n"
            "with stop._cond:  # what Event.wait holds between its lock acquisitions\n"
            "    stop_handler(stop)(signal.SIGTERM, None)\n"
            "    print(stop.is_set())\n"
            "print(stop.wait(20))\n")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=TIMEOUT_S)  # fmt: skip
    assert out.stdout.split() == ["False", "True"]
