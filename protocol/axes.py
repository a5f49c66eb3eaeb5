"""The sensor's axes onto the body's: which sensor axis is body Right, Front and Up, and its sign."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

AXIS_NAMES = ("x", "y", "z")


def axis_map(axes: Sequence[str]) -> np.ndarray:
    """The 3×3 matrix C_s^b (body = C_s^b · sensor) of ``axes``: the sensor axis (``"x"``, ``"-y"``, …) that is body
    Right, Front, Up in that order. ValueError unless each sensor axis appears once and the set is right-handed."""
    if len(axes) != 3:
        raise ValueError(f"expected 3 axes (body Right, Front, Up), got {len(axes)}")
    C_s_b = np.zeros((3, 3))
    for row, text in enumerate(axes):
        name = text.removeprefix("-")
        if name not in AXIS_NAMES:
            raise ValueError(f"{text!r} is not a sensor axis (x, y, z, each with an optional \"-\")")
        C_s_b[row, AXIS_NAMES.index(name)] = -1.0 if text.startswith("-") else 1.0
    if sorted(a.removeprefix("-") for a in axes) != list(AXIS_NAMES):
        raise ValueError(f"{list(axes)} must name each of x, y, z once")
    if np.linalg.det(C_s_b) < 0:
        raise ValueError(f"{list(axes)} is a left-handed set: flip one axis (a \"-\" prefix) or swap two")
    return C_s_b
