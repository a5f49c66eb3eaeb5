"""Checks between the decoders and the pipeline: what may be aligned, what must be bridged or restarted.

The strapdown integration needs every increment: a lost sample removes a slice of rotation and
velocity from the integrals, and a clipped one puts a wrong one in. So, per decoded sample:

- time not after the previous sample → dropped (``time_not_increasing``);
- a gap of up to ``max_bridge_samples`` missing samples (from the time stamps) → the missing
  increments are interpolated linearly between the samples on either side (``samples_bridged``);
  the error is second order in the gap length on a smooth motion;
- a longer gap, or a saturated (full-scale) value → the alignment restarts from the next good
  sample (``restarts``, with the reason in ``last_error``): nothing converged survives on data
  the estimator never saw.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..protocol.counters import Counters


@dataclass(slots=True)
class GateCounters(Counters):
    time_not_increasing: int = 0
    samples_bridged: int = 0
    gaps_bridged: int = 0
    restarts: int = 0
    saturated: int = 0
    status_flagged: int = 0



@dataclass(slots=True)
class Segment:
    """Rows (N, 7) of t, Δθ, Δv to align; ``restart`` says the alignment starts over before them."""

    rows: np.ndarray
    restart: bool
    reason: str | None = None


@dataclass(slots=True)
class SampleGate:
    rate_hz: float
    max_bridge_samples: int = 5
    counters: GateCounters = field(default_factory=GateCounters)
    last_error: str | None = None
    _last: np.ndarray | None = None     # the last row admitted: t, Δθ, Δv

    def admit(self, samples: list[tuple[float, tuple, tuple, int, bool]]) -> list[Segment]:
        """Decoded samples (t, Δθ, Δv, status, saturated) in arrival order → segments to align."""
        dt = 1.0 / self.rate_hz
        segments: list[Segment] = []
        rows: list[np.ndarray] = []
        restart, reason = False, None
        for t, dtheta, dv, status, saturated in samples:
            row = np.array((t, *dtheta, *dv), dtype=float)
            if self._last is not None and not t > self._last[0]:
                self.counters.time_not_increasing += 1
                self.last_error = f"sample at t = {t:.6f} s does not follow t = {self._last[0]:.6f} s: dropped"
                continue
            if status:
                self.counters.status_flagged += 1
            if saturated:
                self.counters.saturated += 1
                restart, reason = self._cut(segments, rows, restart, reason, f"saturated sample at t = {t:.6f} s")
                rows, self._last = [], None
                continue
            if self._last is not None:
                missing = round((t - self._last[0]) / dt) - 1
                if 0 < missing <= self.max_bridge_samples:
                    rows.extend(self._bridge(self._last, row, missing))
                elif missing > self.max_bridge_samples:
                    restart, reason = self._cut(segments, rows, restart, reason,
                                                f"gap of {missing} samples before t = {t:.6f} s")
                    rows = []
            rows.append(row)
            self._last = row
        if rows:
            segments.append(Segment(np.array(rows), restart, reason))
        return segments

    def _cut(self, segments: list[Segment], rows: list, restart: bool, reason: str | None,
             why: str) -> tuple[bool, str]:
        """Close the current segment; the next one restarts the alignment."""
        if rows:
            segments.append(Segment(np.array(rows), restart, reason))
        self.counters.restarts += 1
        self.last_error = f"{why}: alignment restarted"
        return True, self.last_error

    def _bridge(self, before: np.ndarray, after: np.ndarray, missing: int) -> list[np.ndarray]:
        self.counters.gaps_bridged += 1
        self.counters.samples_bridged += missing
        fractions = np.arange(1, missing + 1) / (missing + 1)
        bridged = before + fractions[:, None] * (after - before)
        return list(bridged)
