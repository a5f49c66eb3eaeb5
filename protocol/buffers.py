"""Arrays for one read's worth of data, from buffers of a few sizes.

A daemon that reads whatever arrived allocates arrays of every length in turn. numpy keeps freed buffers under
1 KiB per size for reuse, and the C library's allocator keeps freed chunks per size class: with every length
coming by in turn (a line caught up after a stall, a long flat-out run) those caches fill over hours, and the
resident memory grows with them. An array whose buffer holds the next power of two of its rows comes in a few sizes
only, and the caches stay as they are after the first reads.
"""
from __future__ import annotations

import numpy as np


def read_sized(rows: int, *row_shape: int, dtype: type | np.dtype = np.float64) -> np.ndarray:
    """An uninitialised (rows, *row_shape) array of ``dtype`` whose buffer holds the next power of two of rows."""
    return np.empty((1 << max(rows - 1, 0).bit_length(), *row_shape), dtype=dtype)[:rows]
