"""Shared fixtures: Monte Carlo runs are computed once per session and shared by the tests; a pty pair for the
transports' tests (helpers shared as plain functions live in tests/support/)."""
from __future__ import annotations

import pytest
from sinsalign.tools.evaluate import COARSE_ONLY, monte_carlo
from sinsalign.tools.virtual_imu import PtyPair

SEEDS = range(20)


@pytest.fixture(scope="session")
def swing_runs():
    """The seed-000 swing scenario, 20 seeds, the coarse stage of the default configuration alone (auto: OPREQ here,
    with the swing-bias fit)."""
    return monte_carlo("seed000-swing", SEEDS, COARSE_ONLY, progress=False)


@pytest.fixture
def pty_pair():
    """A pseudo-terminal pair (the virtual IMU's side and the daemon's serial port), closed after the test."""
    pair = PtyPair()
    yield pair
    pair.close()
