"""The compass loops the kernel tests run: a navigation-grade IMU at a mid-latitude site, on the default schedule."""
from __future__ import annotations

import numpy as np
from sinsalign.service.align.compass import CompassLoops, GainSchedule
from sinsalign.service.align.earth import Site
from sinsalign.service.align.sensor_model import SensorGrade
from sinsalign.service.config import CompassConfig

SITE = Site(np.radians(39.9), np.radians(116.4), 50.0)


def default_loops() -> CompassLoops:
    """Loops for gyro 0.01°/h (ARW 0.001°/√h), accelerometer 50 µg (10 µg/√Hz) at :data:`SITE`, the configured
    default gain schedule (levelling, then the azimuth loop from 30 s)."""
    c = CompassConfig()
    return CompassLoops(SITE, SensorGrade.from_datasheet(0.01, 0.001, 50.0, 10.0),
                        GainSchedule(c.schedule_time_s, c.level_sigma, c.azimuth_sigma))
