"""What the readers' numpy fast paths share (``_fast_dataflash``, ``_fast_mcap``,
``_fast_cdr``, ``_fast_ulog``): the fallback signal and the one-stride field gather."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


class Fallback(Exception):
    """The fast path does not cover this file: the reason, for the reader's note."""


def field_at(buf: NDArray[np.uint8], offs: NDArray[np.int64], dtype: np.dtype[Any]
             ) -> NDArray[Any]:
    """The ``dtype`` value at each byte offset ``offs`` of ``buf``: one numpy gather
    through a view of ``buf`` with a stride of one byte (unaligned loads), not a
    gather of every byte of every message. ``offs`` must leave room for the value."""
    n = len(buf) - dtype.itemsize + 1
    if n <= 0:
        return np.zeros(0, dtype=dtype)
    view: NDArray[Any] = np.ndarray(shape=(n,), dtype=dtype, buffer=buf, strides=(1,))
    return view[offs]
