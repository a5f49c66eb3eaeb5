"""A land vehicle with a GNSS receiver and an odometer (or DVL): the fix's lat_deg, lon_deg, h_m, V^n (6) and body
velocity V^b (3) per sample, the gyro rate appended for the lever arms.

Coarse stage: the GNSS one (service/modes/gnss.py) with a second pair per fix, the odometer's V^b against the fix's
V^n: one velocity in two frames (:class:`~service.align.gnss_aided.BodyVelocityPairs`). They hold the heading from
the first fixes on, where velocity integration alone waits for accelerations and the odometer's window for its full
length. Fine stage, as soon as the coarse heading σ is within ``fine.kalman.handover_heading_sigma_deg`` (no earlier
than ``aiding.gnss.handover_s``): the error-state Kalman filter (a datasheet bank) with all three measurements,
the odometer's body velocity (its scale factor and lever arm as states if their priors are set), the GNSS velocity
and position.
Through a GNSS outage the filter goes on with the odometer (the velocity error stays bounded, the heading holds on
the gyros); the fixes rejoin through the χ² gate.
"""
from __future__ import annotations

import numpy as np

from ..align.coarse import InertialCoarseAlignment
from ..align.conventions import dcm_from_quat
from ..align.datasheet_bank import DatasheetBank
from ..align.gnss_aided import GNSS_COLUMNS, BodyVelocityPairs
from .gnss import gnss_coarse, gnss_coarse_counters, gnss_filter_measurements, gnss_handover, gnss_measurements
from .kalman import KalmanMode
from .odometer import odometer_measurement

ODO_COLUMNS = 3
RATE_COLUMN = GNSS_COLUMNS + ODO_COLUMNS
"""The step's aiding values: the fix (6), V^b (3), then the gyro rate (3)."""


class OdometerGnss(KalmanMode):
    aids = (("gnss", GNSS_COLUMNS), ("odo", ODO_COLUMNS))
    coarse_kind = "gnss"
    gyro_rate = True

    def make_coarse(self) -> InertialCoarseAlignment:
        ad = self.p.config.aiding
        coarse = gnss_coarse(self.p, rate_column=RATE_COLUMN)
        coarse.body_velocity = BodyVelocityPairs(GNSS_COLUMNS, np.array(ad.odo.lever_m), ad.odo.vel_std_mps)
        return coarse

    def make_fine(self) -> DatasheetBank | None:
        ad = self.p.config.aiding
        return self.filter_bank(lambda: [odometer_measurement(ad), *gnss_filter_measurements(ad)])

    @staticmethod
    def _split(aid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(V^b (3), the fix (6), the gyro rate (3)) of one step's aiding values."""
        return aid[GNSS_COLUMNS:RATE_COLUMN], aid[:GNSS_COLUMNS], aid[RATE_COLUMN:]

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """The odometer's V^b, then the fix's velocity (with the gyro rate) and position."""
        v_b, fix, gyro_rate = self._split(aid)
        return [("odo", "odo", v_b), *gnss_measurements(fix, gyro_rate)]

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """The filter's step once it runs; before it, the GNSS hand-over."""
        p = self.p
        if p.fine is None or self.kalman_step(dalpha, dt_s, dcm_from_quat(q_b_b0), aid, fresh):
            return
        _, fix, gyro_rate = self._split(aid)
        gnss_handover(p, self, t_end, elapsed_s, q_b_b0, fix, gyro_rate)

    def counters(self) -> dict[str, int]:
        """The filter's counts and the coarse stage's screen of the fixes."""
        return {**super().counters(), **gnss_coarse_counters(self.p)}


MODE = OdometerGnss
"""The mode this module declares (:data:`~service.modes.MODES`)."""
