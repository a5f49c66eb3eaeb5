"""``sensor_msgs/msg/Imu`` from attitude records, CDR-encoded with its 4-byte encapsulation header (the payload
zenoh-bridge-ros2dds forwards to and from DDS), without I/O; docs/outputs.md describes it.

Axes. ROS (REP-103, REP-145) wants the orientation of a forward-left-up (FLU) body in an East-North-Up world
frame; ours is C_b^n of a Right-Front-Up body in ENU (service/align/conventions.py). The FLU axes in RFU
components are forward = y, left = -x, up = z, so C_flu^rfu = Rz(+90°) and

    C_flu^n = C_rfu^n · C_flu^rfu,    q_ros = q_ours ⊗ [cos 45°, 0, 0, sin 45°]

(written x, y, z, w as ROS orders it). Heading 0 (forward along North) is a ROS yaw of +90°: ROS yaw turns
counter-clockwise from East.

Covariance (rad², row-major about the FLU axes): roll about forward and pitch about left take the level σ, yaw
the heading σ; no cross terms. Angular velocity and linear acceleration are not given: their covariance[0] is -1,
the message's way to say so. The stamp is the record's ``t`` (s since the Unix epoch).
"""
from __future__ import annotations

import math

import numpy as np

from .results import ResultRecord

IMU_TYPE = "sensor_msgs/msg/Imu"
HALF = math.sqrt(0.5)
NOT_PROVIDED = np.array([-1.0, *[0.0] * 8])


def ros_quaternion(q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """(x, y, z, w) of C_flu^n from our [w, x, y, z] of C_rfu^n: q ⊗ [½√2, 0, 0, ½√2], written out."""
    w, x, y, z = q
    return HALF * (x + y), HALF * (y - x), HALF * (z + w), HALF * (w - z)


def orientation_covariance(record: ResultRecord) -> np.ndarray:
    """The 9 row-major entries (rad²) about the FLU axes: level σ² on roll and pitch, heading σ² on yaw."""
    level, heading = math.radians(record.level_sigma_deg) ** 2, math.radians(record.heading_sigma_deg) ** 2
    return np.diag([level, level, heading]).ravel()


def stamp(t_s: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in s, nanosec in [0, 1e9)."""
    nanoseconds = round(t_s * 1e9)
    return nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000


class ImuEncoder:
    """CDR ``sensor_msgs/msg/Imu`` with ``frame_id``; needs rosbags (the ros2 extra): ImportError without it."""

    def __init__(self, frame_id: str) -> None:
        from rosbags.typesys import Stores, get_typestore  # the optional extra: imported only when enabled
        self.frame_id = frame_id
        self._store = get_typestore(Stores.ROS2_HUMBLE)
        types = self._store.types
        self._imu, self._header, self._time = (types[IMU_TYPE], types["std_msgs/msg/Header"],
                                               types["builtin_interfaces/msg/Time"])
        self._quaternion, self._vector = types["geometry_msgs/msg/Quaternion"], types["geometry_msgs/msg/Vector3"]

    def encode(self, record: ResultRecord) -> bytes:
        sec, nanosec = stamp(record.t)
        x, y, z, w = ros_quaternion(record.q)
        zero = self._vector(x=0.0, y=0.0, z=0.0)
        message = self._imu(header=self._header(stamp=self._time(sec=sec, nanosec=nanosec), frame_id=self.frame_id),
                            orientation=self._quaternion(x=x, y=y, z=z, w=w),
                            orientation_covariance=orientation_covariance(record), angular_velocity=zero,
                            angular_velocity_covariance=NOT_PROVIDED, linear_acceleration=zero,
                            linear_acceleration_covariance=NOT_PROVIDED)
        return bytes(self._store.serialize_cdr(message, IMU_TYPE))
