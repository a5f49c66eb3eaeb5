"""Checks between the decoders and the pipeline: what may be aligned, what must be bridged or restarted.

The strapdown integration needs every increment: a lost sample removes a slice of rotation and
velocity from the integrals, and a clipped one puts a wrong one in. So, per decoded sample:

- time not after the previous sample → dropped (``time_not_increasing``);
- a gap of up to ``max_bridge_samples`` missing samples (from the time stamps) → the missing
  increments are interpolated linearly between the samples on either side (``samples_bridged``);
  the error is second order in the gap length on a smooth motion;
- a longer gap, or a saturated (full-scale) value → the alignment restarts from the next good
  sample (``restarts``, with the reason in ``last_error``), in the call that brings it if not this
  one: nothing converged survives on data the estimator never saw.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from ..protocol.counters import Counters

Sample = tuple[float, tuple, tuple, int, bool]
"""A decoded IMU sample: t (s), Δθ (3,) rad, Δv (3,) m/s, status word, saturated (a value at full scale)."""


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
    """Admits decoded samples in calls of any size: the same samples give the same segments and counters
    however they are split into calls (a cut at the end of one call restarts the segment the next one begins)."""

    rate_hz: float
    max_bridge_samples: int = 5
    counters: GateCounters = field(default_factory=GateCounters)
    last_error: str | None = None
    _last: np.ndarray | None = None     # the last row admitted: t (s), Δθ (rad), Δv (m/s)
    _restart_reason: str | None = None   # a cut no segment has carried yet: why the next segment restarts

    def admit(self, samples: Iterable[Sample]) -> list[Segment]:
        """Decoded samples in arrival order → segments to align; a segment carries the restart of every cut since the
        previous segment, whichever call made it."""
        dt = 1.0 / self.rate_hz
        segments: list[Segment] = []
        rows: list[np.ndarray] = []
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
                self._cut(segments, rows, f"saturated sample at t = {t:.6f} s")
                rows, self._last = [], None
                continue
            if self._last is not None:
                missing = round((t - self._last[0]) / dt) - 1
                if 0 < missing <= self.max_bridge_samples:
                    rows.extend(self._bridge(self._last, row, missing))
                elif missing > self.max_bridge_samples:
                    self._cut(segments, rows, f"gap of {missing} samples before t = {t:.6f} s")
                    rows = []
            rows.append(row)
            self._last = row
        self._close(segments, rows)
        return segments

    def _close(self, segments: list[Segment], rows: list[np.ndarray]) -> None:
        """The rows since the last cut as a segment, which takes the pending restart (none without rows)."""
        if rows:
            segments.append(Segment(np.array(rows), self._restart_reason is not None, self._restart_reason))
            self._restart_reason = None

    def _cut(self, segments: list[Segment], rows: list[np.ndarray], why: str) -> None:
        """Close the current segment; the next one, in this call or a later one, restarts the alignment."""
        self._close(segments, rows)
        self.counters.restarts += 1
        self.last_error = self._restart_reason = f"{why}: alignment restarted"

    def _bridge(self, before: np.ndarray, after: np.ndarray, missing: int) -> list[np.ndarray]:
        self.counters.gaps_bridged += 1
        self.counters.samples_bridged += missing
        fractions = np.arange(1, missing + 1) / (missing + 1)
        bridged = before + fractions[:, None] * (after - before)
        return list(bridged)
