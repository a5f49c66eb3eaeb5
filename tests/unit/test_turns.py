"""The turn watch (service/align/turns.py): whether a fixed base's mean attitude has moved.

GIVEN the body attitudes of 0.1-s control steps, WHEN the body swings ±10° about a steady mean (periods of 5-10 s)
or stays still while the Earth turns it, THEN no event; WHEN it is indexed 90° about the vertical, THEN one TURNED
while it turns and one STEADY once it has stayed put for the anchor's refresh, and again at the next index; WHEN it
turns steadily at any rate a turn is seen at (0.1 or 0.5°/s), THEN one TURNED and never STEADY; the events fall at
the same steps however the steps are split into calls.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sinsalign.service.align.conventions import DEG, dcm_from_euler, quat_from_dcm
from sinsalign.service.align.earth import OMEGA_IE
from sinsalign.service.align.turns import ANCHOR_REFRESH_S, STEADY, TURN_WINDOW_S, TURNED, TurnWatch

STEP_S = 0.1
WINDOW_STEPS = round(TURN_WINDOW_S / STEP_S)


def attitudes(t: np.ndarray, heading: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """q_b^{b0} (K, 4) of a body with these Euler angles (rad) on an Earth turning about a 45° axis."""
    axis = np.array([0.0, np.cos(45 * DEG), np.sin(45 * DEG)])
    C = []
    for k in range(len(t)):
        angle = OMEGA_IE * t[k]
        K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        earth = np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K
        C.append(earth @ dcm_from_euler(heading[k], pitch[k], roll[k]))
    return np.array([quat_from_dcm(c) for c in C])


def indexed(t: np.ndarray) -> np.ndarray:
    """Heading (rad) of a table indexed 90° (raised-cosine, 20 s) at 300 s and 700 s."""
    heading = np.zeros_like(t)
    for start in (300.0, 700.0):
        x = np.clip((t - start) / 20.0, 0.0, 1.0)
        heading += 90 * DEG * 0.5 * (1.0 - np.cos(np.pi * x))
    return heading


def events_of(t: np.ndarray, q: np.ndarray, split: int | None = None) -> list[tuple[float, int]]:
    watch = TurnWatch(WINDOW_STEPS)
    step = split or len(t)
    found = []
    for k in range(0, len(t), step):
        found += [(float(t[k + j]), event) for j, event in watch.scan(t[k:k + step], q[k:k + step])]
    return found


@pytest.mark.parametrize("period_s", [5.0, 8.0, 10.0])
def test_a_swing_about_a_steady_mean_is_no_turn(period_s):
    t = np.arange(1, 6001) * STEP_S
    w = 2 * np.pi / period_s
    q = attitudes(t, 10 * DEG * np.sin(w * t), 10 * DEG * np.sin(1.3 * w * t + 1.0), 10 * DEG * np.cos(0.8 * w * t))
    assert events_of(t, q) == []


def test_a_still_body_on_the_turning_earth_is_no_turn():
    t = np.arange(1, 36001) * STEP_S   # an hour: the Earth turns it 15°
    zero = np.zeros_like(t)
    assert events_of(t, attitudes(t, zero, zero + 5 * DEG, zero)) == []


def test_each_index_is_a_turn_then_steady_after_the_refresh():
    t = np.arange(1, 11001) * STEP_S
    zero = np.zeros_like(t)
    found = events_of(t, attitudes(t, indexed(t), zero + 5 * DEG, zero))
    assert [event for _, event in found] == [TURNED, STEADY, TURNED, STEADY]
    (turn1, _), (steady1, _), (turn2, _), (steady2, _) = found
    assert 300.0 < turn1 < 320.0 and 700.0 < turn2 < 720.0   # within the 20-s turn
    # the mean settles within a window, then stays put for the refresh
    assert 320.0 + ANCHOR_REFRESH_S <= steady1 < 320.0 + TURN_WINDOW_S + ANCHOR_REFRESH_S
    assert 720.0 + ANCHOR_REFRESH_S <= steady2 < 720.0 + TURN_WINDOW_S + ANCHOR_REFRESH_S


@pytest.mark.parametrize("rate_deg_s", [0.1, 0.5])
def test_a_continuous_rotation_is_turning_for_ever(rate_deg_s):
    t = np.arange(1, 12001) * STEP_S
    zero = np.zeros_like(t)
    found = events_of(t, attitudes(t, rate_deg_s * DEG * t, zero, zero))
    assert [event for _, event in found] == [TURNED]


@functools.cache
def swinging_indexed() -> tuple[np.ndarray, np.ndarray, list[tuple[float, int]]]:
    """(t, q_b^{b0}, its events in one call) of an indexed table that also swings 3° in heading."""
    t = np.arange(1, 11001) * STEP_S
    zero = np.zeros_like(t)
    q = attitudes(t, indexed(t) + 3 * DEG * np.sin(t), zero + 5 * DEG, zero)
    return t, q, events_of(t, q)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 3000))
def test_the_events_fall_at_the_same_steps_however_the_calls_split_them(split):
    t, q, whole = swinging_indexed()
    assert len(whole) == 4 and events_of(t, q, split) == whole
