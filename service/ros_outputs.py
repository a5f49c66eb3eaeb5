"""The ROS 2 output: each record as a CDR ``sensor_msgs/msg/Imu`` (protocol/ros_imu.py) on ``<prefix>/<unit>/ros/imu``,
which zenoh-bridge-ros2dds routes to the ROS 2 topic of the same name (docs/outputs.md)."""
from __future__ import annotations

import zenoh

from ..protocol.keys import UnitKeys
from ..protocol.results import ResultRecord
from ..protocol.ros_imu import ImuEncoder
from .config import ConfigError, Ros2Config

ROS2_EXTRA = "[ros2] needs the ros2 extra: pip install 'sinsalign[ros2]'"


class RosImuOutput:
    """A publisher of ``keys.ros_imu``; ConfigError (:data:`ROS2_EXTRA`) if rosbags is not installed."""

    def __init__(self, session: zenoh.Session, keys: UnitKeys, config: Ros2Config) -> None:
        try:
            self._encoder = ImuEncoder(config.frame_id)
        except ImportError:
            raise ConfigError(ROS2_EXTRA) from None
        self._publisher = session.declare_publisher(keys.ros_imu)

    def records(self, records: list[ResultRecord]) -> None:
        for record in records:
            self._publisher.put(self._encoder.encode(record))

    def close(self) -> None:
        self._publisher.undeclare()
