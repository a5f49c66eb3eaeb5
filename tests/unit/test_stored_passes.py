"""The stored-data passes run a pass's stretch in one compiled call (service/align/stored.py).

GIVEN a store of control steps (step lengths that differ in their last bits, as a replay's time stamps give them),
a live state on the gain schedule's ramp and live steps queued meanwhile, WHEN the passes run in slices of any size
(one step per call, the live daemon's slice, all at once), THEN the state after each call, the catch-up and what each
call returns are the same bits as the passes stepped one at a time with :meth:`CompassLoops.step`, backward first.
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from sinsalign.service.align.compass import CompassLoops, CompassState
from sinsalign.service.align.conventions import dcm_from_euler
from sinsalign.service.align.stored import RepeatedNavigation, StepBuffer
from support.compass_loops import SITE, default_loops

STORED = 37
PAIRS = 2


class SingleSteps:
    """The passes one :meth:`CompassLoops.step` at a time (a generator of steps): each pass turns the state round,
    then runs the store backward or forward; the catch-up after them; over at the first call finding no step."""

    def __init__(self, loops: CompassLoops, state: CompassState, buffer: StepBuffer, pairs: int) -> None:
        self.loops, self.state, self.buffer, self.pairs = loops, state.copy(), buffer, pairs
        self.catch_up: list[tuple[np.ndarray, float]] = []
        self.passes_done, self.steps_run = False, 0
        self._work = self._steps()

    def _steps(self) -> Iterator[None]:
        n = self.buffer.count
        for _ in range(self.pairs):
            for order in (range(n - 1, -1, -1), range(n)):
                self.loops.reverse(self.state)
                for i in order:
                    self.loops.step(self.state, self.buffer.dalpha[i], float(self.buffer.dt_s[i]), False)
                    yield

    def run(self, max_steps: int | None) -> bool:
        steps = 0
        while max_steps is None or steps < max_steps:
            if not self.passes_done:
                if next(self._work, self) is self:   # the generator is exhausted
                    self.passes_done = True
                    continue
            elif self.catch_up:
                self.loops.step(self.state, *self.catch_up.pop(0))
            else:
                return True
            steps += 1
            self.steps_run += 1
        return self.passes_done and not self.catch_up


def setup(t_loop_s: float) -> tuple[CompassLoops, CompassState, StepBuffer, list[np.ndarray]]:
    rng = np.random.default_rng(7)
    loops, site = default_loops(), SITE
    C_b_n = dcm_from_euler(0.3, -0.2, 1.1)
    gravity_b = C_b_n.T @ np.array([0.0, 0.0, site.gravity])
    buffer = StepBuffer(STORED)
    t = 80.0 + np.cumsum(np.full(STORED + 1, 0.1))   # step lengths of 0.1 s apart in their last bits
    for k in range(STORED):
        buffer.append(gravity_b * 0.1 + rng.normal(0.0, 1e-4, 3), float(t[k + 1] - t[k]))
    assert len(np.unique(buffer.dt_s)) > 1
    state = loops.start(dcm_from_euler(2e-3, -1e-3, 0.02) @ C_b_n, np.eye(3), 1e-3, 0.03, t_loop_s=t_loop_s)
    live = [gravity_b * 0.1 + rng.normal(0.0, 1e-4, 3) for _ in range(5)]
    return loops, state, buffer, live


def same(a: CompassState, b: CompassState) -> bool:
    return (np.array_equal(a.C_b0_p, b.C_b0_p) and np.array_equal(a.V, b.V) and np.array_equal(a.P, b.P)
            and (a.I_E, a.I_N, a.y, a.t_loop_s, a.azimuth_on, a.earth_sign)
            == (b.I_E, b.I_N, b.y, b.t_loop_s, b.azimuth_on, b.earth_sign))


@pytest.mark.parametrize("t_loop_s", [25.0, 31.0, 60.0])
@pytest.mark.parametrize("slice_steps", [1, 5, STORED, STORED + 1, 2 * STORED, None])
def test_passes_in_any_slices_are_the_single_steps(slice_steps: int | None, t_loop_s: float) -> None:
    """At loop times before the azimuth loop (25 s), as it takes over within the passes' held gains (31 s: its
    first step switches it on) and on the schedule's ramp (60 s: the catch-up steps change the gains)."""
    loops, state, buffer, live = setup(t_loop_s)
    compiled, oracle = RepeatedNavigation(loops, state, buffer, PAIRS), SingleSteps(loops, state, buffer, PAIRS)
    calls = 0
    while True:
        if calls < len(live):   # live steps arrive while the passes run
            compiled.queue(live[calls], 0.1)
            oracle.catch_up.append((live[calls].copy(), 0.1))
        done = compiled.run(slice_steps)
        assert done == oracle.run(slice_steps)
        assert same(compiled.state, oracle.state) and compiled.steps_run == oracle.steps_run
        calls += 1
        if done and calls >= len(live):
            break
    assert compiled.steps_run == 2 * PAIRS * STORED + len(live)
