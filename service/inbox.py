"""The hand-over from Zenoh's threads to the daemon's loop: a queue bounded in messages and in bytes.

A Zenoh callback must return at once (a slow one stalls the session's reads, and the sender's queue drops), so it
only puts the payload here; the loop drains it. A peer may send anything: 300 messages of 8 MB each must not take
the daemon to gigabytes, so a message larger than any valid one is refused outright and the queue holds at most
``max_bytes`` in all.
"""
from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

Item = TypeVar("Item")

MAX_MESSAGE_BYTES = 4096
"""An IMU message is about 100 bytes and an aiding one 200: a payload 20 times that is no message of ours."""


class Inbox(Generic[Item]):
    """Thread-safe FIFO of (item, its size in bytes); :meth:`put` refuses what would exceed a limit."""

    def __init__(self, max_messages: int, max_bytes: int, max_message_bytes: int = MAX_MESSAGE_BYTES) -> None:
        self.max_messages = max_messages
        self.max_bytes = max_bytes
        self.max_message_bytes = max_message_bytes
        self.oversized = 0      # refused: larger than any valid message
        self.overflow = 0       # refused: the queue was full (messages or bytes)
        self._items: deque[tuple[Item, int]] = deque()
        self._bytes = 0
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)

    def put(self, item: Item, size: int) -> bool:
        """Queue ``item`` of ``size`` bytes; False (counted) if it is oversized or the queue is full."""
        with self._lock:
            if size > self.max_message_bytes:
                self.oversized += 1
                return False
            if len(self._items) >= self.max_messages or self._bytes + size > self.max_bytes:
                self.overflow += 1
                return False
            self._items.append((item, size))
            self._bytes += size
            self._ready.notify()
            return True

    def drain(self, wait_s: float = 0.0) -> list[Item]:
        """Everything queued, oldest first; waits up to ``wait_s`` for the first item if there is none."""
        with self._lock:
            if not self._items and wait_s > 0.0:
                self._ready.wait(wait_s)
            items = [item for item, _ in self._items]
            self._items.clear()
            self._bytes = 0
            return items

    @property
    def queued_bytes(self) -> int:
        return self._bytes
