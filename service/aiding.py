"""Aiding epochs on the IMU's time line: latency, order, gaps, and interpolation to IMU samples.

Whatever the source (an aiding log, the serial aiding message, ``…/aid/<kind>`` on Zenoh),
epochs pass through an :class:`AidingTrack`: their time stamps are moved back by the configured
latency, an epoch not after the previous one is dropped and counted (a repeat if it carries the
same time, out of order otherwise), and a value at any IMU sample time comes from linear
interpolation between the two epochs around it, or nothing (counted) when they are further
apart than ``max_gap_s`` or the sample lies outside them. Nothing here is fatal.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..protocol.counters import Counters


@dataclass(slots=True)
class AidingCounters(Counters):
    epochs: int = 0
    repeats: int = 0
    out_of_order: int = 0
    non_finite: int = 0
    gaps: int = 0                 # epochs that follow the previous one by more than max_gap_s
    unaided_queries: int = 0      # IMU times asked for without two epochs around them



@dataclass(slots=True)
class AidingTrack:
    """The two latest usable epochs of one aiding stream (bounded memory).

    latency_s : how late the stream's time stamps are (subtracted).
    max_gap_s : two epochs further apart than this are not interpolated across.
    """

    latency_s: float = 0.0
    max_gap_s: float = 1.0
    counters: AidingCounters = field(default_factory=AidingCounters)
    _prev: np.ndarray | None = None      # (1 + n,) time and values
    _last: np.ndarray | None = None

    def push(self, rows: np.ndarray) -> None:
        """Epochs (N, 1 + n): time stamp (s, the stream's clock) then the values."""
        for row in np.atleast_2d(np.asarray(rows, dtype=float)):
            if not np.isfinite(row).all():
                self.counters.non_finite += 1
                continue
            row = row.copy()
            row[0] -= self.latency_s
            if self._last is not None and not row[0] > self._last[0]:
                if row[0] == self._last[0]:
                    self.counters.repeats += 1
                else:
                    self.counters.out_of_order += 1
                continue
            if self._last is not None and row[0] - self._last[0] > self.max_gap_s:
                self.counters.gaps += 1
            self._prev, self._last = self._last, row
            self.counters.epochs += 1

    @property
    def latest_time(self) -> float | None:
        """Time (IMU clock) of the newest epoch; values up to it can be interpolated."""
        return None if self._last is None else float(self._last[0])

    def at(self, t: float) -> np.ndarray | None:
        """Values at IMU time ``t`` by linear interpolation between the two latest epochs, else None."""
        if self._prev is None or not self._prev[0] <= t <= self._last[0] \
                or self._last[0] - self._prev[0] > self.max_gap_s:
            self.counters.unaided_queries += 1
            return None
        f = (t - self._prev[0]) / (self._last[0] - self._prev[0])
        return self._prev[1:] + f * (self._last[1:] - self._prev[1:])
