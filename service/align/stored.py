"""Stored-data repeated navigation (seed 001 §2.3, "Scheme 2"; docs/algorithms/compass.md, "Stored data").

The first ``T_s`` seconds of control steps are kept (the b0-frame velocity increment Δα and the
step length of each: 4 floats per step, a fixed array sized at start, never more). When they are
all in, a clone of the compass state runs the loops backward over them, forward again, and so on
for the configured number of pairs, then catches up on the steps that arrived meanwhile and
replaces the live state. The passes keep the gain schedule where it was (the loop stays as wide
as it was when the buffer filled) and consume no schedule time.

The caller decides how many steps run per call: all of them in offline replay, a bounded slice per
live block in the daemon. Each call runs its stretch of a pass in one compiled loop
(:meth:`CompassLoops.steps_held`), the same steps on the same data in the same order as one at a
time, so the state that comes out is bit-identical however the passes are sliced.
"""
from __future__ import annotations

from collections import deque

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
        self._pass = 0   # passes begun: the odd-numbered ones (the first, third …) run backward
        self._done_in_pass = buffer.count   # steps of the current pass run (none begun: the last one complete)

    def queue(self, dalpha_b0: np.ndarray, dt_s: float) -> None:
        """A live step that the clone must also run once the passes are over."""
        self.catch_up.append((np.array(dalpha_b0, dtype=float), float(dt_s)))

    def _run_passes(self, max_steps: int) -> int:
        """Run up to ``max_steps`` (≥ 1) pass steps, a pass's stretch in one compiled call; how many ran (0: the
        passes are over)."""
        n = self.buffer.count
        while self._done_in_pass == n:   # once, but for an empty store: every pass turns round and ends at once
            if self._pass == 2 * self.pairs:
                return 0
            self.loops.reverse(self.state)
            self._pass, self._done_in_pass = self._pass + 1, 0
        take = min(max_steps, n - self._done_in_pass)
        if self._pass % 2:   # backward: from the newest stored step
            first = n - 1 - self._done_in_pass
            rows = slice(first, first - take if first - take >= 0 else None, -1)
        else:
            rows = slice(self._done_in_pass, self._done_in_pass + take)
        self.loops.steps_held(self.state, self.buffer.dalpha[rows], self.buffer.dt_s[rows])
        self._done_in_pass += take
        return take

    def run(self, max_steps: int | None = None) -> bool:
        """Run up to ``max_steps`` steps (all if None); True once passes and catch-up are done. The passes count as
        over at the first call that finds no pass step left, as the catch-up then begins."""
        steps = 0
        while max_steps is None or steps < max_steps:
            if not self.passes_done:
                ran = self._run_passes(self.buffer.count * 2 * self.pairs if max_steps is None
                                       else max_steps - steps)
                if ran == 0:
                    self.passes_done = True
                    continue
                steps += ran
                self.steps_run += ran
                continue
            if self.catch_up:
                dalpha, dt_s = self.catch_up.popleft()
                self.loops.step(self.state, dalpha, dt_s)
            else:
                return True
            steps += 1
            self.steps_run += 1
        return self.passes_done and not self.catch_up
