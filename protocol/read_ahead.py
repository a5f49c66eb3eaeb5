"""Reading ahead in a thread of its own: a log's next blocks are read and parsed while the caller works on the last.

The compiled row parser runs without the interpreter's lock (protocol/_rows.pyx), so on a machine with a second core
the reading of a CSV log costs the replay almost nothing of its own time.
"""
from __future__ import annotations

import threading
from collections.abc import Iterable, Iterator
from queue import Full, Queue
from typing import TypeVar

T = TypeVar("T")

_END = object()
_POLL_S = 0.1
"""How often a producer waiting for room looks whether its consumer has stopped."""


def read_ahead(items: Iterable[T], depth: int = 2) -> Iterator[T]:
    """The items of ``items`` in order, produced by a thread up to ``depth`` items ahead of the consumer. An exception
    the producer raises is raised here in its place, after the items before it; a consumer that stops early (closes
    the iterator, or fails) stops the producer at its next item."""
    queue: Queue[tuple[object, BaseException | None]] = Queue(depth)
    stopped = threading.Event()

    def put(entry: tuple[object, BaseException | None]) -> bool:
        while not stopped.is_set():
            try:
                queue.put(entry, timeout=_POLL_S)
                return True
            except Full:
                continue
        return False

    def produce() -> None:
        iterator = iter(items)
        try:
            for item in iterator:
                if not put((item, None)):
                    return
            put((_END, None))
        except BaseException as exc:   # handed to the consumer, raised there
            put((_END, exc))
        finally:
            close = getattr(iterator, "close", None)   # a generator's files, closed in this thread
            if close is not None:
                close()

    thread = threading.Thread(target=produce, name="read-ahead", daemon=True)
    thread.start()
    try:
        while True:
            item, exc = queue.get()   # the producer ends with an entry, unless this side stopped it
            if exc is not None:
                raise exc
            if item is _END:
                return
            yield item   # type: ignore[misc]
    finally:
        stopped.set()
        thread.join()
