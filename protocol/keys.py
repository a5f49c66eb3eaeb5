"""Zenoh key expressions of one unit: ``<prefix>/<unit>/imu``, ``…/aid/<kind>``, ``…/attitude``,
``…/status``, the liveliness token ``…/alive``, the read-only queryable ``…/state`` and the ROS 2 output
``…/ros/imu`` (``sensor_msgs/msg/Imu``, CDR: zenoh-bridge-ros2dds makes it the topic ``/<prefix>/<unit>/ros/imu``)."""
from __future__ import annotations

from dataclasses import dataclass

FORBIDDEN = set("*$#?")


def check_chunks(text: str, what: str) -> str:
    """``text`` if it is a concrete key expression (no wildcards, no empty chunks), else ValueError."""
    if not text or any(c in FORBIDDEN for c in text) or any(not chunk for chunk in text.split("/")):
        raise ValueError(f"{what} {text!r} must be non-empty key chunks without * $ # ? or empty '/' parts")
    return text


@dataclass(frozen=True, slots=True)
class UnitKeys:
    prefix: str = "sinsalign"
    unit: str = "unit1"

    def __post_init__(self) -> None:
        check_chunks(self.prefix, "prefix")
        check_chunks(self.unit, "unit id")
        if "/" in self.unit:
            raise ValueError(f"unit id {self.unit!r} must be a single key chunk")

    def _key(self, *parts: str) -> str:
        return "/".join((self.prefix, self.unit, *parts))

    @property
    def imu(self) -> str:
        return self._key("imu")

    def aid(self, kind: str) -> str:
        return self._key("aid", check_chunks(kind, "aiding kind"))

    @property
    def attitude(self) -> str:
        return self._key("attitude")

    @property
    def status(self) -> str:
        return self._key("status")

    @property
    def alive(self) -> str:
        return self._key("alive")

    @property
    def state(self) -> str:
        return self._key("state")

    @property
    def ros_imu(self) -> str:
        return self._key("ros", "imu")

    @property
    def all_units(self) -> str:
        """Key expression matching every unit's keys under the prefix (for watch clients)."""
        return f"{self.prefix}/*"
