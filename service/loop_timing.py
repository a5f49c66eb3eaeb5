"""The daemon's own share of a frame's latency: from the moment a read returned with samples to the moment the last
of their records was handed to the outputs (decoding, the sample checks, the alignment, the messages and their puts).

What a subscriber sees as frame → attitude latency adds to this the operating system's wake-ups (the daemon's on the
line, each transport thread's, the subscriber's own) and the network. The status carries this share per status period
(median, 99th percentile and largest over the reads that brought samples) and the largest since the start, so that an
integrator can tell a daemon that falls behind from a loaded machine or network. Beside each read's time the loop
thread's CPU time over it: a read whose time is far above its CPU time waited for the processor (another thread or
process ran, or the virtual machine was held), not for its own work.
"""
from __future__ import annotations

import numpy as np

CAPACITY = 8192
"""Reads kept per status period for its percentiles (the latest ones when a period holds more: a 5-kHz IMU read one
frame at a time fills 5000 a second); the period's largest is exact however many there were."""


class LoopTiming:
    """Read-to-published times (s in, ms out) of the loop's reads that brought samples."""

    def __init__(self, capacity: int = CAPACITY) -> None:
        self._ms = np.empty(capacity)
        self._reads = 0
        self._max_ms = 0.0
        self._max_cpu_ms = 0.0
        self.max_ms_since_start = 0.0

    def add(self, seconds: float, cpu_seconds: float) -> None:
        """One read's time from its return to its records' hand-over (s), and the loop thread's CPU time over it (s)."""
        ms = seconds * 1e3
        self._ms[self._reads % len(self._ms)] = ms
        self._reads += 1
        self._max_cpu_ms = max(self._max_cpu_ms, cpu_seconds * 1e3)
        if ms > self._max_ms:
            self._max_ms = ms
            self.max_ms_since_start = max(self.max_ms_since_start, ms)

    def summary(self, advance: bool = False) -> dict[str, float | int | None]:
        """The status's ``loop`` map: ``reads`` this period, ``p50_ms``, ``p99_ms`` and ``max_ms`` over them and
        ``max_cpu_ms``, the largest CPU time of one (None without any), ``max_ms_since_start``; ``advance`` (the
        periodic status) starts the next period."""
        kept = self._ms[:min(self._reads, len(self._ms))]
        p50, p99 = (float(p) for p in np.percentile(kept, (50.0, 99.0))) if len(kept) else (None, None)
        summary = {"reads": self._reads, "p50_ms": p50, "p99_ms": p99, "max_ms": self._max_ms if len(kept) else None,
                   "max_cpu_ms": self._max_cpu_ms if len(kept) else None, "max_ms_since_start": self.max_ms_since_start}
        if advance:
            self._reads = 0
            self._max_ms = self._max_cpu_ms = 0.0
        return summary
