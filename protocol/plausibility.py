"""What a sensor can physically send: the limits every received aiding epoch is held to.

A value can be well-formed and finite and still be impossible (an odometer at 1e308 m/s, a latitude of 95°, a
quaternion of norm 7). Such a value never reaches an estimator: its linearisation would turn it into a covariance
no eigen-solver survives. The decoders (Zenoh messages, serial aiding frames) and the aiding logs reject it as they
reject a malformed one. The IMU's increments are held to its stated ranges by the sample gate
(service/sample_gate.py).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

MAX_ODO_SPEED_MPS = 300.0
"""An odometer or DVL: a high-speed train runs at 100 m/s; three times that is no vehicle on wheels or water."""
MAX_GNSS_SPEED_MPS = 600.0
"""A GNSS receiver: civil receivers stop reporting at 515 m/s (export rules)."""
MAX_MASTER_SPEED_MPS = 1200.0
"""A master INS: a carrier aircraft at Mach 3."""
LATITUDE_RANGE_DEG = (-90.0, 90.0)
LONGITUDE_RANGE_DEG = (-180.0, 180.0)
HEIGHT_RANGE_M = (-12_000.0, 100_000.0)
"""The deepest ocean floor to the edge of space (m above the ellipsoid)."""
QUATERNION_NORM_TOLERANCE = 1e-3
"""A master's attitude quaternion is of unit norm: float32 rounding is 1e-7; a norm off by more is not a rotation
anyone sent."""

SPEED_LIMITS_MPS = {"odo": MAX_ODO_SPEED_MPS, "gnss": MAX_GNSS_SPEED_MPS, "master": MAX_MASTER_SPEED_MPS}
SPEED_FIELDS = {"odo": "v_b", "gnss": "v_enu", "master": "v_enu"}


def position_problem(lat_deg: float, lon_deg: float, h_m: float) -> str | None:
    """Why (lat_deg, lon_deg, h_m) is no place on Earth, or None."""
    if not LATITUDE_RANGE_DEG[0] <= lat_deg <= LATITUDE_RANGE_DEG[1]:
        return f"latitude {lat_deg:.6g}° is outside ±{LATITUDE_RANGE_DEG[1]:g}°"
    if not LONGITUDE_RANGE_DEG[0] <= lon_deg <= LONGITUDE_RANGE_DEG[1]:
        return f"longitude {lon_deg:.6g}° is outside ±{LONGITUDE_RANGE_DEG[1]:g}°"
    if not HEIGHT_RANGE_M[0] <= h_m <= HEIGHT_RANGE_M[1]:
        return f"height {h_m:.6g} m is outside {HEIGHT_RANGE_M[0]:g}..{HEIGHT_RANGE_M[1]:g} m"
    return None


def aiding_problem(kind: str, values: Mapping[str, Sequence[float]]) -> str | None:
    """Why an aiding epoch of ``kind`` (its fields by name, as :data:`~.messages.AIDING_FIELDS`) is physically
    impossible, or None; every value is finite already."""
    speed = math.hypot(*values[SPEED_FIELDS[kind]])
    if speed > SPEED_LIMITS_MPS[kind]:
        return f"speed {speed:.6g} m/s is above the {SPEED_LIMITS_MPS[kind]:g} m/s a {kind} source can report"
    if "lat_deg" in values:
        problem = position_problem(values["lat_deg"][0], values["lon_deg"][0], values["h_m"][0])
        if problem is not None:
            return problem
    if "q" in values:
        norm = math.sqrt(math.fsum(c * c for c in values["q"]))
        if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            return f"quaternion of norm {norm:.6g}, not a rotation"
    return None
