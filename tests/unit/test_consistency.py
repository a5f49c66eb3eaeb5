"""The consistency monitor (service/align/consistency.py): estimates that differ by more than their σ allow.

GIVEN converged estimates of C_b0^n0 kept once a second, WHEN a new one has turned from one of them by more than
K (σ then + σ now) plus the floor, about any axis and by any angle up to 180°, THEN it is a contradiction that names
the angle, the time between and what σ allowed; within that, none. Estimates not reported converged are compared
but never kept: an early estimate's σ is no bound on it.
"""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.service.align.consistency import CONTRADICTION_SIGMAS, FLOOR_DEG, INTERVAL_S, ConsistencyMonitor
from sinsalign.service.align.conventions import DEG, quat_from_dcm


def turned(angle_deg: float, axis: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    """q_b0^n0 of a fixed C_b0^n0 turned by ``angle_deg`` about ``axis`` (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    a = angle_deg * DEG
    R = np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * K @ K
    base = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return quat_from_dcm(R @ base)


def sigma_of(sigma_deg: float):
    return lambda elapsed_s: np.full(np.shape(elapsed_s), sigma_deg)


ALLOWED_DEG = FLOOR_DEG + CONTRADICTION_SIGMAS * (0.05 + 0.05)


@pytest.mark.parametrize(("angle_deg", "axis", "contradicts"), [
    (0.9 * ALLOWED_DEG, (0, 0, 1), False), (1.1 * ALLOWED_DEG, (0, 0, 1), True),
    (1.1 * ALLOWED_DEG, (1, 0, 0), True), (179.0, (0, 0, 1), True), (180.0, (0, 1, 0), True)])
def test_an_estimate_beyond_what_both_sigmas_allow_is_a_contradiction(angle_deg, axis, contradicts):
    monitor = ConsistencyMonitor()
    assert monitor.check(100.0, turned(0.0), 0.05, sigma_of(0.05), keep=True) is None
    found = monitor.check(110.0, turned(angle_deg, axis), 0.05, sigma_of(0.05), keep=True)
    assert (found is not None) == contradicts
    if contradicts:
        assert found.startswith(f"the attitude estimate turned {angle_deg:.3g}° in 10 s where its σ allowed "
                                f"{ALLOWED_DEG:.2g}°")


def test_estimates_not_converged_are_compared_but_never_kept():
    monitor = ConsistencyMonitor()
    assert monitor.check(10.0, turned(0.0), 0.05, sigma_of(0.05), keep=False) is None
    assert monitor.check(11.0, turned(30.0), 0.05, sigma_of(0.05), keep=True) is None   # nothing kept to compare with
    assert monitor.check(12.0, turned(0.0), 0.05, sigma_of(0.05), keep=False) is not None


def test_sigma_then_is_asked_at_the_kept_estimates_times():
    asked: list[list[float]] = []

    def sigma(elapsed_s: np.ndarray) -> np.ndarray:
        asked.append(elapsed_s.tolist())
        return np.where(elapsed_s < 50.0, 10.0, 0.05)   # wide then, narrow now

    monitor = ConsistencyMonitor()
    monitor.check(40.0, turned(0.0), 10.0, sigma, keep=True)
    assert monitor.check(58.0, turned(4.8), 0.05, sigma, keep=True) is None   # within 5 (10 + 0.05)° of the first
    assert monitor.check(60.0, turned(5.0), 0.05, sigma, keep=True) is None
    # σ then is asked only where σ now cannot settle it: the 58-s estimate is within 5 σ now and the floor
    assert asked == [[40.0], [40.0]]
    found = monitor.check(62.0, turned(5.0 + 5.0 * 10.1), 0.05, sigma, keep=True)
    assert found is not None and found.startswith("the attitude estimate turned 55.5° in 22 s where its σ allowed 50°")
    assert monitor.next_s == 62.0 + INTERVAL_S
