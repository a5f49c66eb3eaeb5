"""A source's clock seen through the arrival times of its data: maps one to the other by the least lag.

A GNSS receiver's epoch carries its own time (UTC, GPS time of week), not the IMU's; all the host knows is when
its bytes arrived. The IMU's samples link the two clocks: each sample arrives at some host time after its own
time, late by the transport and the reads' batching, never early. The smallest lag, the largest
t_source − t_arrival over recent samples, is the one least disturbed by batching: an arrival time plus that offset
is the IMU time of bytes that came over a link like the IMU's. The project's frames carry the IMU's own time; a
vendor IMU's are stamped on the host's monotonic clock: the mapping is the same either way.

The receiver's own time of fix is mapped onto the IMU's clock the same way, its epochs' IMU arrival times as the
arrivals: several epochs that came in one read keep their own spacing, and the jitter of the reads leaves the
mapping at its least lag (the receiver's output latency and the transport, which ``[aiding.gnss] latency_s``
takes back).

The offset follows a faster arrival at once and a slower source clock (oscillators drift apart) by at most
:data:`DRIFT_RATE` per second of arrival time, so one late batch does not move it.
"""
from __future__ import annotations

import numpy as np

DRIFT_RATE = 1e-4
"""How fast (s per s) the offset may fall, following a slower source clock: ten times a crystal's 10 ppm."""


class ArrivalClock:
    """The least lag of a source's data behind their arrival; ``offset_s`` (source time − arrival time, s) is None
    before the first."""

    def __init__(self, drift_rate: float = DRIFT_RATE) -> None:
        self.drift_rate = drift_rate
        self.offset_s: float | None = None
        self._arrival_s = 0.0   # the latest arrival (s)

    def observe(self, t_source: np.ndarray, arrival_s: float) -> None:
        """Data with source times ``t_source`` (N,) s that arrived together at ``arrival_s`` (s, the arrival
        clock)."""
        if len(t_source) == 0:
            return
        lead = float(t_source.max()) - arrival_s
        if self.offset_s is None:
            self.offset_s = lead
        else:
            drifted = self.offset_s - self.drift_rate * max(arrival_s - self._arrival_s, 0.0)
            self.offset_s = max(lead, drifted)
        self._arrival_s = arrival_s

    def source_time(self, arrival_s: float) -> float | None:
        """The source time (s) of data that arrived at ``arrival_s``; None before any."""
        return None if self.offset_s is None else arrival_s + self.offset_s

    def arrival_time(self, t_source: float) -> float | None:
        """The least arrival time (s) of data of source time ``t_source``; None before any."""
        return None if self.offset_s is None else t_source - self.offset_s
