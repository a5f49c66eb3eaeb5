"""Arrays for a read's worth of data come from buffers of a power of two of rows (protocol/buffers.py)."""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.protocol.buffers import read_sized


@pytest.mark.parametrize(("rows", "capacity"), [(0, 1), (1, 1), (2, 2), (3, 4), (64, 64), (65, 128), (1300, 2048)])
def test_a_read_s_array_has_its_rows_in_a_power_of_two_buffer(rows: int, capacity: int) -> None:
    a = read_sized(rows, 9)
    assert a.shape == (rows, 9) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable
    assert a.base is not None and a.base.shape == (capacity, 9)
    flags = read_sized(rows, dtype=np.bool_)
    assert flags.shape == (rows,) and flags.dtype == np.bool_ and flags.base.shape == (capacity,)


def test_lengths_of_a_day_s_reads_share_a_few_buffer_sizes() -> None:
    """Every read length up to 64 KiB of frames (1300) in 12 buffer sizes, not 1300."""
    sizes = {read_sized(n, 9).base.nbytes for n in range(1, 1301)}
    assert len(sizes) == 12
