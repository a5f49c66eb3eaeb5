"""The daemon's recording of its raw input: an IMU log (the pinned CSV, or its binary form for a path ending in
``.sbin``) of every admitted sample, with a restart mark wherever the alignment started over, so that ``replay`` of
it makes the daemon's decisions and gives its records bit for bit. Owner-only, never through a link (the customer's
data)."""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ..protocol.imu_binary import SUFFIX, BinaryLogWriter
from ..protocol.imu_log import CsvLogWriter
from .config import Config
from .safe_files import open_private


def open_log_writer(path: str | Path, values: Mapping[str, object]) -> CsvLogWriter | BinaryLogWriter:
    """An owner-only IMU log at ``path`` with the header ``values``: binary if the name ends in ``.sbin``."""
    if str(path).endswith(SUFFIX):
        return BinaryLogWriter(open_private(path, "wb"), values)
    return CsvLogWriter(open_private(path), values)


def open_recording(path: str, config: Config) -> CsvLogWriter | BinaryLogWriter:
    """An open recording at ``path`` for ``config``'s site, rate and datasheet (its header): ``rows`` (N, 7: t in s,
    Δθ in rad, Δv in m/s) of admitted samples, ``restart(why)`` where the alignment started over."""
    s, sensor = config.site, config.sensor
    return open_log_writer(path, {
        "lat_deg": s.lat_deg, "lon_deg": s.lon_deg, "height_m": s.height_m, "rate_hz": config.imu.rate_hz,
        "gyro_bias_deg_h": sensor.gyro_bias_deg_h, "gyro_arw_deg_rth": sensor.gyro_arw_deg_rth,
        "acc_bias_ug": sensor.acc_bias_ug, "acc_vrw_ug_rthz": sensor.acc_vrw_ug_rthz})
