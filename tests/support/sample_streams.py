"""Decoded IMU samples for the sample gate's tests."""
import numpy as np


def stream(times: np.ndarray) -> np.ndarray:
    """Samples (N, 9) at ``times`` (s), small increments, status 0, none saturated."""
    rows = np.zeros((len(times), 9))
    rows[:, 0] = times
    rows[:, 1] = 1e-6
    rows[:, 6] = 0.05
    return rows
