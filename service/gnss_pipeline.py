"""The GNSS-aided pipeline (in-flight alignment, seed 004): the same pipeline, other parts.

It is :class:`AlignmentPipeline` with the observation source swapped for the VIF or PIF source
(service/align/gnss_aided.py: GNSS antenna velocity and position, lever arm compensated), the
centred solver weighted by the pairs' stated noise and screening each pair against the fit (a
glitch is left out and counted), σ from the fit itself, and no translation check (this base flies).
From ``aiding.gnss_handover_s`` on (once the coarse heading σ is at most
``aiding.handover_heading_sigma_deg``) the fine stage is the error-state Kalman filter with GNSS
velocity and position measurements (lever arm in both), gated by χ²: it rides through outages on
the IMU alone, with σ growing. The gyro rate each fix needs for the lever arm is appended to the GNSS
columns (:class:`GyroRateAidPipeline`).
"""
from __future__ import annotations

import numpy as np

from .align.coarse import InertialCoarseAlignment
from .align.conventions import DEG, dcm_from_quat
from .align.gnss_aided import GNSS_COLUMNS, GnssPositionSource, GnssSource, GnssVelocitySource
from .align.kalman import ErrorStateFilter, GnssPosition, GnssVelocity, antenna_lever_velocity, enu_to_geodetic_step
from .align.sensor_model import SIGMA_UNKNOWN_DEG
from .align.solvers import CentredWahba
from .kalman_stage import GyroRateAidPipeline

PAIR_GATE_CHI2 = 36.0
"""The coarse stage's screen of each pair: |e|²/μ over the fit's residual variance (6σ in 3-D, a false alarm
in ~1e-6 pairs; at the Kalman gate's 16.3 the seed-004 runs lost 0-2 good pairs in 60 s). A 20-m/s glitch
is 200σ."""
HANDOVER_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n and position from one fix: their σ is this many times the fix's."""


class GnssCoarseAlignment(InertialCoarseAlignment):
    """The inertial-frame coarse stage with σ from the centred fit's own covariance (manoeuvres, not the
    Earth's rotation, carry the heading here, so the fixed-site σ model does not apply) and the pairs
    weighted by the source's stated noise."""

    source: GnssSource

    def observe(self, elapsed_s: np.ndarray, q_b_b0: np.ndarray, alpha: np.ndarray, aid: np.ndarray | None = None,
                aid_epoch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.source.accumulate(elapsed_s, alpha)
        self.source.follow(elapsed_s, aid)
        return super().observe(elapsed_s, q_b_b0, alpha, aid, aid_epoch)

    def prepare_pairs(self, elapsed_s: np.ndarray, b: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pairs weighted by the source's stated noise, with its drift regressor if it has one."""
        return self.solver.prepare(b, r, self.source.observation_variance(elapsed_s),
                                   self.source.drift_regressor(elapsed_s))

    def sigma(self, elapsed_s: float) -> tuple[float, float]:
        covariance = self.solver.covariance()
        if covariance is None:
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        heading, level = np.sqrt(covariance[2, 2]), np.sqrt(0.5 * (covariance[0, 0] + covariance[1, 1]))
        factor = self.source.sigma_factor
        return (min(float(factor * heading / DEG), SIGMA_UNKNOWN_DEG),
                min(float(factor * level / DEG), SIGMA_UNKNOWN_DEG))


class GnssAidedPipeline(GyroRateAidPipeline):
    """Alignment in flight with GNSS fixes (6 aiding values per sample: lat_deg, lon_deg, h_m, V^n)."""

    aid_width = GNSS_COLUMNS
    aid_kind = "gnss"
    checks_translation = False

    def _make_coarse(self) -> InertialCoarseAlignment:
        a, ad = self.config.alignment, self.config.aiding
        source_class = GnssPositionSource if ad.gnss_formula == "pif" else GnssVelocitySource
        source = source_class(self.site, np.array(ad.gnss_lever_m), ad.gnss_vel_std_mps, ad.gnss_pos_std_m)
        # the pairs are screened against the fit (a glitch of the fixes would otherwise enter it for good)
        solver = CentredWahba(weighted=True, gate_chi2=PAIR_GATE_CHI2, drift=source.drift)
        return GnssCoarseAlignment(source, self.grade, solver, self.sample_period_s, a.obs_interval_s,
                                   a.disturbance_velocity_mps)

    def _make_fine(self) -> ErrorStateFilter | None:
        if not self.config.fine.enabled:
            return None
        ad = self.config.aiding
        lever = np.array(ad.gnss_lever_m)
        return ErrorStateFilter(self.grade, [GnssVelocity(ad.gnss_vel_std_mps, lever),
                                             GnssPosition(ad.gnss_pos_std_m, lever)], ad.gate_chi2)

    def _measurements(self, aid: np.ndarray) -> list[tuple[str, np.ndarray]]:
        """The fix's velocity with the gyro rate (lever arm), and its position in rad / m."""
        return [("gnss_vel", aid[3:9]), ("gnss_pos", np.r_[aid[:2] * DEG, aid[2]])]

    def _stage_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray,
                    dt_s: float, aid: np.ndarray | None, fresh: bool) -> None:
        """The Kalman stage's step once it runs; before it, the hand-over from the coarse stage. ``aid``: the fix at
        the step's end, then the gyro rate (3, rad/s)."""
        C_b_b0 = dcm_from_quat(q_b_b0)
        if self.fine is None or self._kalman_step(dalpha, dt_s, C_b_b0, aid, fresh):
            return
        ad = self.config.aiding
        if not np.isfinite(aid).all() or elapsed_s + 1e-9 < ad.gnss_handover_s:
            return
        solution = self._handover_solution(t_end, q_b_b0, ("", f" at {elapsed_s:.0f} s: the Kalman stage waits "
                                                                  "(manoeuvre)"))
        if solution is None:
            return
        C_b_n = dcm_from_quat(solution.q_b_n)
        antenna = np.r_[aid[:2] * DEG, aid[2]]
        lever = np.array(ad.gnss_lever_m)
        V_n = aid[3:6] - antenna_lever_velocity(C_b_n, aid[6:9], antenna[0], lever)
        position = antenna - enu_to_geodetic_step(C_b_n @ lever, antenna)
        self.fine.start(C_b_n, C_b_b0, V_n, position, solution.level_sigma_deg * DEG,
                        solution.heading_sigma_deg * DEG, HANDOVER_SIGMA_FACTOR * ad.gnss_vel_std_mps,
                        velocity_from_attitude=False, position_sigma_m=HANDOVER_SIGMA_FACTOR * ad.gnss_pos_std_m)

    def aiding_counters(self) -> dict[str, int]:
        """What the estimators made of the fixes: coarse observations awaiting or without one, coarse pairs screened
        out (glitches) and screens reopened after a run of rejections, and the Kalman stage's accepted
        and gated-out velocity and position fixes."""
        return {**super().aiding_counters(), "gnss_coarse_rejected": self.coarse.solver.rejected,
                "gnss_coarse_reopened": self.coarse.solver.reopened}
