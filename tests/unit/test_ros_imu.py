"""The ROS 2 Imu message (protocol/ros_imu.py) decoded by rosbags: the orientation is our attitude in ROS's axes
(C_ros = C_ours · C_flu^rfu), the covariances and the stamp as documented, and the daemon refuses ``[ros2]``
without rosbags."""
from __future__ import annotations

import sys

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sinsalign.protocol.keys import UnitKeys
from sinsalign.protocol.results import ResultRecord
from sinsalign.protocol.ros_imu import IMU_TYPE, ImuEncoder
from sinsalign.service.align.conventions import DEG, dcm_from_euler, dcm_from_quat, euler_from_dcm, quat_from_dcm
from sinsalign.service.config import ConfigError, Ros2Config
from sinsalign.service.ros_outputs import ROS2_EXTRA, RosImuOutput

C_FLU_RFU = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
"""FLU body axes in RFU components: forward = y, left = -x, up = z."""
STORE = get_typestore(Stores.ROS2_HUMBLE)


def record(C_b_n: np.ndarray, t: float = 1_764_680_400.123456789, heading_sigma_deg: float = 0.2,
           level_sigma_deg: float = 0.01) -> ResultRecord:
    heading, pitch, roll = euler_from_dcm(C_b_n)
    return ResultRecord(t=t, phase="aligned", q=tuple(quat_from_dcm(C_b_n)), pitch_deg=pitch / DEG,
                        roll_deg=roll / DEG, heading_deg=heading / DEG, heading_sigma_deg=heading_sigma_deg,
                        level_sigma_deg=level_sigma_deg, converged=True, rho=0.0, trace_P=0.0, n_obs=0)


def decode(data: bytes):
    assert data[:4] == b"\x00\x01\x00\x00"   # CDR, little endian: the encapsulation header
    return STORE.deserialize_cdr(data, IMU_TYPE)


def ros_dcm(message) -> np.ndarray:
    o = message.orientation
    return dcm_from_quat(np.array([o.w, o.x, o.y, o.z]))


def test_random_attitudes_come_back_in_ros_axes() -> None:
    rng = np.random.default_rng(5)
    encoder = ImuEncoder("imu_link")
    for _ in range(20):
        q = rng.normal(size=4)
        C = dcm_from_quat(q / np.linalg.norm(q))
        message = decode(encoder.encode(record(C)))
        assert np.abs(ros_dcm(message) - C @ C_FLU_RFU).max() < 1e-6
        o = message.orientation
        assert abs(np.linalg.norm([o.x, o.y, o.z, o.w]) - 1.0) < 1e-12


def test_heading_zero_is_a_ros_yaw_of_90_degrees_and_heading_90_a_yaw_of_0() -> None:
    encoder = ImuEncoder("imu_link")
    for heading_deg, yaw_deg in ((0.0, 90.0), (90.0, 0.0), (180.0, -90.0)):
        C_ros = ros_dcm(decode(encoder.encode(record(dcm_from_euler(heading_deg * DEG, 0.0, 0.0)))))
        assert np.degrees(np.arctan2(C_ros[1, 0], C_ros[0, 0])) == pytest.approx(yaw_deg, abs=1e-9)
        assert np.allclose(C_ros @ [1.0, 0.0, 0.0], [np.sin(heading_deg * DEG), np.cos(heading_deg * DEG), 0.0])


def test_covariances_stamp_and_frame_id() -> None:
    message = decode(ImuEncoder("base_imu").encode(record(np.eye(3), heading_sigma_deg=0.5, level_sigma_deg=0.02)))
    level, heading = (0.02 * DEG) ** 2, (0.5 * DEG) ** 2
    assert np.allclose(message.orientation_covariance, np.diag([level, level, heading]).ravel(), rtol=1e-12, atol=0)
    for covariance in (message.angular_velocity_covariance, message.linear_acceleration_covariance):
        assert covariance[0] == -1.0
    assert (message.header.stamp.sec, message.header.frame_id) == (1_764_680_400, "base_imu")
    assert abs(message.header.stamp.nanosec - 123_456_789) < 1000


def test_without_rosbags_the_daemon_refuses_ros2_in_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rosbags.typesys", None)   # import fails as if the extra were not installed
    with pytest.raises(ConfigError) as refused:
        RosImuOutput(None, UnitKeys(), Ros2Config(enabled=True))
    assert str(refused.value) == ROS2_EXTRA and "\n" not in ROS2_EXTRA
