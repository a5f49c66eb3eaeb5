"""``sinsalign convert``: an IMU log from the pinned CSV to its binary form or back, samples and restart marks
exact (docs/reference.md, "Binary IMU log")."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from sinsalign.protocol.imu_log import open_imu_log
from sinsalign.service.recording import open_log_writer


def convert(source: str | Path, target: str | Path) -> int:
    """Write the IMU log ``source`` (either form, told by its first line) to ``target``, binary if its name ends in
    ``.sbin``, else CSV (owner-only, as a recording); the number of samples. Every sample is read back as written,
    whatever it holds, and every value is checked as any reader checks it (finite, time increasing)."""
    log = open_imu_log(source)
    writer = open_log_writer(target, log.header.values)
    samples = 0
    try:
        for reason, t, dtheta, dv in log.segments():
            if reason is not None:
                writer.restart(reason)
            if len(t):
                writer.rows(np.column_stack((t, dtheta, dv)))
                samples += len(t)
    finally:
        writer.close()
    return samples
