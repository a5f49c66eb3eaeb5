"""A log read ahead in a thread (protocol/read_ahead.py) gives the consumer what the log's own iterator gives.

GIVEN an iterator of blocks, one that fails part-way and a consumer that stops early, WHEN read ahead, THEN the items
come in order, the failure is raised after the items before it (the same exception), the producer never runs more
than its depth ahead, and a consumer that stops closes the log's iterator and leaves no thread behind.
"""
from __future__ import annotations

import threading
from collections.abc import Iterator

import numpy as np
import pytest
from sinsalign.protocol.imu_log import LogFormatError
from sinsalign.protocol.read_ahead import read_ahead


def test_items_come_in_order() -> None:
    blocks = [np.full(3, k, dtype=float) for k in range(50)]
    got = list(read_ahead(iter(blocks), depth=2))
    assert len(got) == 50 and all(g is b for g, b in zip(got, blocks, strict=True))
    assert list(read_ahead(iter([]))) == []


def test_a_failure_is_raised_after_the_items_before_it() -> None:
    def failing() -> Iterator[int]:
        yield 1
        yield 2
        raise LogFormatError("imu.csv", 7, "dvx", "not a number: 'x'")

    reader = read_ahead(failing())
    assert [next(reader), next(reader)] == [1, 2]
    with pytest.raises(LogFormatError) as info:
        next(reader)
    assert info.value.line == 7


def test_the_producer_runs_at_most_its_depth_ahead_and_stops_with_the_consumer() -> None:
    produced: list[int] = []
    closed = threading.Event()

    def counting() -> Iterator[int]:
        try:
            for k in range(1000):
                produced.append(k)
                yield k
        finally:
            closed.set()

    before = threading.active_count()
    reader = read_ahead(counting(), depth=3)
    assert next(reader) == 0
    threading.Event().wait(0.3)   # time for the producer to fill the queue
    # the one taken, three queued, one produced and waiting for room
    assert len(produced) <= 1 + 3 + 1
    reader.close()
    assert closed.wait(2.0) and threading.active_count() == before
