"""Stored-data repeated navigation (seed 001 §2.3, "Scheme 2"; docs/algorithms/compass.md, "Stored data").

The first ``T_s`` seconds of control steps are kept (the b0-frame velocity increment Δα and the
step length of each: 4 floats per step, a fixed array sized at start, never more). When they are
all in, a clone of the compass state runs the loops backward over them, forward again, and so on
for the configured number of pairs, then catches up on the steps that arrived meanwhile and
replaces the live state. The passes keep the gain schedule where it was (the loop stays as wide
as it was when the buffer filled) and consume no schedule time.

The work is a generator of single steps, so the caller decides how much runs per call: all of it
in offline replay, a bounded slice per live block in the daemon. Both run the same steps on the
same data in the same order, so the state that comes out is bit-identical.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterator

import numpy as np

from .compass import CompassLoops, CompassState


class StepBuffer:
    """A fixed-capacity store of control steps: Δα (m/s, b0 axes) and the step length (s)."""

    def __init__(self, capacity_steps: int) -> None:
        self.dalpha = np.empty((capacity_steps, 3))
        self.dt_s = np.empty(capacity_steps)
        self.count = 0

    @property
    def capacity(self) -> int:
        return len(self.dt_s)

    @property
    def full(self) -> bool:
        return self.count == self.capacity

    def append(self, dalpha_b0: np.ndarray, dt_s: float) -> None:
        if self.full:
            raise OverflowError("step buffer is full")
        self.dalpha[self.count] = dalpha_b0
        self.dt_s[self.count] = dt_s
        self.count += 1


class RepeatedNavigation:
    """Backward/forward passes over a :class:`StepBuffer` on a clone of the live compass state."""

    def __init__(self, loops: CompassLoops, state: CompassState, buffer: StepBuffer, pairs: int) -> None:
        self.loops = loops
        self.state = state.copy()
        self.buffer = buffer
        self.pairs = pairs
        self.catch_up: deque[tuple[np.ndarray, float]] = deque()
        self.steps_run = 0
        self.passes_done = False
        self._work = self._steps()

    def queue(self, dalpha_b0: np.ndarray, dt_s: float) -> None:
        """A live step that the clone must also run once the passes are over."""
        self.catch_up.append((np.array(dalpha_b0, dtype=float), float(dt_s)))

    def _steps(self) -> Iterator[None]:
        n = self.buffer.count
        for _ in range(self.pairs):
            for order in (range(n - 1, -1, -1), range(n)):
                self.loops.reverse(self.state)
                for i in order:
                    dalpha, dt_s = self.buffer.dalpha[i], float(self.buffer.dt_s[i])
                    self.loops.step(self.state, dalpha, dt_s, advance_schedule=False)
                    yield

    def run(self, max_steps: int | None = None) -> bool:
        """Run up to ``max_steps`` steps (all if None); True once passes and catch-up are done."""
        steps = 0
        while max_steps is None or steps < max_steps:
            if not self.passes_done:
                if next(self._work, _DONE) is _DONE:
                    self.passes_done = True
                    continue
            elif self.catch_up:
                dalpha, dt_s = self.catch_up.popleft()
                self.loops.step(self.state, dalpha, dt_s)
            else:
                return True
            steps += 1
            self.steps_run += 1
        return self.passes_done and not self.catch_up


_DONE = object()
