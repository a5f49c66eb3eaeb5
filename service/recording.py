"""The daemon's recording of its raw input: an IMU log (the pinned CSV) of every admitted sample, with a
``# restart: why`` line wherever the alignment started over, so that ``replay`` of it makes the daemon's decisions
and gives its records bit for bit. Owner-only, never through a link (the customer's data)."""
from __future__ import annotations

import numpy as np

from ..protocol.imu_log import IMU_COLUMNS, RESTART_MARKER, write_header, write_rows
from .config import Config
from .safe_files import open_private


class Recording:
    """An open recording at ``path`` for ``config``'s site, rate and datasheet (its header)."""

    def __init__(self, path: str, config: Config) -> None:
        self._stream = open_private(path)
        s, sensor = config.site, config.sensor
        write_header(self._stream, {"lat_deg": s.lat_deg, "lon_deg": s.lon_deg, "height_m": s.height_m,
                                    "rate_hz": config.imu.rate_hz, "gyro_bias_deg_h": sensor.gyro_bias_deg_h,
                                    "gyro_arw_deg_rth": sensor.gyro_arw_deg_rth, "acc_bias_ug": sensor.acc_bias_ug,
                                    "acc_vrw_ug_rthz": sensor.acc_vrw_ug_rthz}, IMU_COLUMNS)

    def rows(self, rows: np.ndarray) -> None:
        """Admitted rows (N, 7: t in s, Δθ in rad, Δv in m/s)."""
        write_rows(self._stream, rows)

    def restart(self, reason: str) -> None:
        """The alignment started over here (one line, whatever the reason's white space)."""
        self._stream.write(f"{RESTART_MARKER} {' '.join(reason.split())}\n")

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        self._stream.close()
