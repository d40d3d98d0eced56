"""The daemon's heap on glibc: fewer malloc arenas, free pages handed back.

Two calls into the C library (``ctypes``, which the daemon's dependencies load anyway),
both no-ops where it is not glibc (musl, macOS) or the call is missing:

* :func:`limit_arenas` (``mallopt(M_ARENA_MAX, ARENA_MAX)``), before any thread starts.
  glibc gives every thread that allocates while another holds an arena a new one, up to
  8 × cores; the Zenoh runtime's threads, the bus reader and OpenBLAS's thread each end
  up with an arena of their own whose partly used pages stay resident. Two arenas are
  enough for a process whose Python side holds the GIL. An operator's ``MALLOC_ARENA_MAX``
  in the environment (glibc reads it itself) wins: it is not overridden.
* :func:`release_free_heap` (``malloc_trim(0)``) once the daemon is up and then every
  :data:`TRIM_PERIOD_S` from the housekeeping: returns the free pages left by start-up
  (the calibration check's arrays, the TOML and JSON parsers' temporaries, Zenoh's
  handshake buffers) and by traffic bursts to the kernel. It walks the heap: ≈ 0.1–1 ms.

Measured by ``bench/footprint.py`` (docs/BENCHMARKS.md, "Footprint"): steady RSS at
2 kHz before and after.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
from typing import Any

log = logging.getLogger(__name__)

#: glibc's ``M_ARENA_MAX`` option number (malloc.h).
M_ARENA_MAX = -8
#: Arenas allowed (glibc's default: 8 per core).
ARENA_MAX = 2
#: Seconds between two ``malloc_trim`` calls in the daemon's housekeeping.
TRIM_PERIOD_S = 30.0


def _libc() -> Any | None:
    name = ctypes.util.find_library("c") or "libc.so.6"
    try:
        lib = ctypes.CDLL(name)
    except OSError:
        return None
    return lib if hasattr(lib, "malloc_trim") and hasattr(lib, "mallopt") else None


_LIBC: Any | None = None
_LOOKED = False


def _glibc() -> Any | None:
    global _LIBC, _LOOKED
    if not _LOOKED:
        _LIBC, _LOOKED = _libc(), True
    return _LIBC


def limit_arenas() -> bool:
    """``mallopt(M_ARENA_MAX, ARENA_MAX)`` unless ``MALLOC_ARENA_MAX`` is set; True if done."""
    if "MALLOC_ARENA_MAX" in os.environ:
        return False
    lib = _glibc()
    return bool(lib is not None and lib.mallopt(M_ARENA_MAX, ARENA_MAX) == 1)


def release_free_heap() -> bool:
    """``malloc_trim(0)``: True when memory was returned to the kernel."""
    lib = _glibc()
    return bool(lib is not None and lib.malloc_trim(0))


__all__ = ["ARENA_MAX", "TRIM_PERIOD_S", "limit_arenas", "release_free_heap"]
