"""In flight with GNSS (seed 004): the fix's lat_deg, lon_deg, h_m and V^n (6 aiding values per sample), the gyro
rate appended for the lever arm.

Observation source: the VIF or PIF source (service/align/gnss_aided.py: antenna velocity and position, lever arm
compensated); solver: the centred fit weighted by the pairs' stated noise, screening each pair against the fit (a
glitch is left out and counted); σ from the fit itself. As soon as the coarse heading σ is within
``fine.kalman.handover_heading_sigma_deg`` (no earlier than ``aiding.gnss.handover_s``) the fine stage is the
error-state Kalman filter with GNSS velocity and position measurements (lever arm in both), gated by χ², run as a
datasheet bank (service/align/datasheet_bank.py): it rides through outages on the IMU alone, with σ growing. No
translation check: this base flies.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..align.coarse import InertialCoarseAlignment
from ..align.conventions import DEG, dcm_from_quat
from ..align.datasheet_bank import DatasheetBank
from ..align.gnss_aided import GNSS_COLUMNS, GnssCoarseAlignment, GnssPositionSource, GnssVelocitySource
from ..align.kalman import (
    GnssPosition,
    GnssVelocity,
    Measurement,
    antenna_lever_velocity,
    enu_to_geodetic_step,
)
from ..align.solvers import CentredWahba
from .kalman import KalmanMode

if TYPE_CHECKING:
    from ..config import AidingConfig
    from ..pipeline import AlignmentPipeline

PAIR_GATE_CHI2 = 36.0
"""The coarse stage's screen of each pair: |e|²/μ over the fit's residual variance (6σ in 3-D, a false alarm
in ~1e-6 pairs; at the Kalman gate's 16.3 the seed-004 runs lost 0-2 good pairs in 60 s). A 20-m/s glitch
is 200σ."""
MANOEUVRE_NOTICE_S = 30.0
"""A coarse heading σ still above the hand-over limit this long (s) after the start is told to the operator as a
flight without the manoeuvre that shows the heading; before it, the fit is still gathering its first fixes."""
HANDOVER_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n and position from one fix: their σ is this many times the fix's."""


def gnss_coarse(p: AlignmentPipeline, rate_column: int = GNSS_COLUMNS) -> GnssCoarseAlignment:
    """The coarse stage on the fixes (VIF or PIF source, the centred fit screening each pair); the gyro rate from
    aid column ``rate_column``."""
    a, ad = p.config.alignment, p.config.aiding
    source_class = GnssPositionSource if ad.gnss.formula == "pif" else GnssVelocitySource
    source = source_class(p.site, np.array(ad.gnss.lever_m), ad.gnss.vel_std_mps, ad.gnss.pos_std_m, rate_column)
    # the pairs are screened against the fit (a glitch of the fixes would otherwise enter it for good)
    solver = CentredWahba(weighted=True, gate_chi2=PAIR_GATE_CHI2, drift=source.drift)
    return GnssCoarseAlignment(source, p.grade, solver, p.sample_period_s, a.obs_interval_s,
                               a.disturbance_velocity_mps)


def gnss_filter_measurements(ad: AidingConfig) -> list[Measurement]:
    """The Kalman stage's GNSS velocity and position measurements, both through the antenna's lever arm."""
    lever = np.array(ad.gnss.lever_m)
    return [GnssVelocity(ad.gnss.vel_std_mps, lever), GnssPosition(ad.gnss.pos_std_m, lever)]


def gnss_measurements(fix: np.ndarray, gyro_rate: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
    """One fix (lat_deg, lon_deg, h_m, V^n (3)) as the filter's measurements: its velocity with the gyro rate
    (rad/s, for the lever arm) and its position in rad / m."""
    return [("gnss", "gnss_vel", np.r_[fix[3:6], gyro_rate]), ("gnss", "gnss_pos", np.r_[fix[:2] * DEG, fix[2]])]


def gnss_handover(p: AlignmentPipeline, mode: KalmanMode, t_end: float, elapsed_s: float, q_b_b0: np.ndarray,
                  fix: np.ndarray, gyro_rate: np.ndarray) -> None:
    """Start ``p``'s filter from the coarse solution and one fix (and the gyro rate, rad/s) once the alignment has
    run ``aiding.gnss.handover_s`` (or earlier, once the gyro's drift outweighs the fit's noise: the coarse σ only
    grows from there) and the coarse heading σ is within the mode's limit."""
    ad = p.config.aiding
    if not np.isfinite(fix).all() or (elapsed_s + 1e-9 < ad.gnss.handover_s
                                      and not p.coarse.drift_dominates(elapsed_s)):
        return
    notice = ("", f" at {elapsed_s:.0f} s: the Kalman stage waits (manoeuvre)")
    solution = mode.handover_solution(t_end, q_b_b0, notice if elapsed_s >= MANOEUVRE_NOTICE_S else None)
    if solution is None:
        return
    C_b_n = dcm_from_quat(solution.q_b_n)
    antenna = np.r_[fix[:2] * DEG, fix[2]]
    lever = np.array(ad.gnss.lever_m)
    V_n = fix[3:6] - antenna_lever_velocity(C_b_n, gyro_rate, antenna[0], lever)
    position = antenna - enu_to_geodetic_step(C_b_n @ lever, antenna)
    p.fine.start(C_b_n, dcm_from_quat(q_b_b0), V_n, position, solution.level_sigma_deg * DEG,
                 solution.heading_sigma_deg * DEG, HANDOVER_SIGMA_FACTOR * ad.gnss.vel_std_mps,
                 velocity_from_attitude=False, position_sigma_m=HANDOVER_SIGMA_FACTOR * ad.gnss.pos_std_m)


def gnss_coarse_counters(p: AlignmentPipeline) -> dict[str, int]:
    """The coarse pairs screened out (glitches) and screens reopened after a run of rejections."""
    return {"gnss_coarse_rejected": p.coarse.solver.rejected, "gnss_coarse_reopened": p.coarse.solver.reopened}


class Gnss(KalmanMode):
    aids = (("gnss", GNSS_COLUMNS),)
    coarse_kind = "gnss"
    gyro_rate = True

    def make_coarse(self) -> InertialCoarseAlignment:
        return gnss_coarse(self.p)

    def make_fine(self) -> DatasheetBank | None:
        return self.filter_bank(lambda: gnss_filter_measurements(self.p.config.aiding))

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """The fix's velocity with the gyro rate (lever arm), and its position in rad / m."""
        return gnss_measurements(aid[:GNSS_COLUMNS], aid[GNSS_COLUMNS:])

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """The Kalman stage's step once it runs; before it, the hand-over from the coarse stage. ``aid``: the fix at
        the step's end, then the gyro rate (3, rad/s)."""
        p = self.p
        if p.fine is None or self.kalman_step(dalpha, dt_s, dcm_from_quat(q_b_b0), aid, fresh):
            return
        gnss_handover(p, self, t_end, elapsed_s, q_b_b0, aid[:GNSS_COLUMNS], aid[GNSS_COLUMNS:])

    def counters(self) -> dict[str, int]:
        """The filter's counts and the coarse stage's screen."""
        return {**super().counters(), **gnss_coarse_counters(self.p)}


MODE = Gnss
"""The mode this module declares (:data:`~service.modes.MODES`)."""
