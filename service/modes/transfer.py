"""Transfer alignment of a slave IMU against a master INS (seed 002, dual model): the master's quaternion of
C_bm^n, V^n ENU m/s, lat_deg, lon_deg, h_m (10 aiding values per sample), the slave's gyro rate appended.

Phase 1 (``coarse``) is the inertial-frame stage with the master source (service/align/transfer.py): velocity and
attitude pairs r = M b solved in closed form for the mounting M = C_bs^bm, whatever its size. Phase 2 (``fine`` →
``aligned``) is the error-state Kalman filter with velocity matching (the master's velocity, with the lever arm as
states) and attitude matching (the mounting as states), from the first control step at which phase 1's σ is within
``aiding.master.handover_sigma_deg``, or within ``aiding.master.linear_sigma_deg`` (the filter's linear range) and
no longer improving (a MEMS slave), or at ``aiding.master.handover_s`` (the seed's fixed 10 s). The slave's attitude
is the output; every record carries the mounting with its σ (:meth:`Transfer.mounting`).
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ...protocol.results import ResultRecord
from ..align.coarse import InertialCoarseAlignment
from ..align.conventions import DEG, dcm_from_euler, dcm_from_quat, quat_from_dcm
from ..align.kalman import ErrorStateFilter, GnssVelocity, LeverVelocity, MasterAttitude, antenna_lever_velocity
from ..align.sensor_model import SIGMA_UNKNOWN_DEG
from ..align.solvers import GroupedWahba
from ..align.transfer import MASTER_COLUMNS, MasterCoarseAlignment, MasterSource, correlate_handover
from .kalman import KalmanMode

if TYPE_CHECKING:
    from ..config import MasterConfig

HANDOVER_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n from one master epoch: its σ is this many times the stated noise."""


def master_velocity(master: MasterConfig, lever_b: np.ndarray | None = None) -> GnssVelocity | LeverVelocity:
    """The master's velocity as the filter's measurement of the point at ``lever_b`` (slave body axes, m), that
    lever arm estimated from there (``aiding.master.lever_sigma_m`` > 0) or taken as known."""
    if master.lever_sigma_m > 0.0:
        return LeverVelocity(master.vel_std_mps, lever_b, master.lever_sigma_m, name="master_vel")
    return GnssVelocity(master.vel_std_mps, lever_b, name="master_vel")


class Transfer(KalmanMode):
    aids = (("master", MASTER_COLUMNS),)
    coarse_kind = "master"
    gyro_rate = True
    handover_limit_key = "aiding.master.linear_sigma_deg"

    def make_coarse(self) -> InertialCoarseAlignment:
        p = self.p
        a, ad = p.config.alignment, p.config.aiding
        source = MasterSource(p.site, ad.master.att_std_deg * DEG, ad.master.vel_std_mps, p.grade.gyro_bias_rad_s,
                              p.grade.acc_bias_ms2, np.array(ad.master.lever_m))
        coarse = MasterCoarseAlignment(source, p.grade, GroupedWahba(2), p.sample_period_s, a.obs_interval_s,
                                       a.disturbance_velocity_mps)
        if ad.master.mount_deg:
            coarse.nominal = (dcm_from_euler(*(np.array(ad.master.mount_deg) * DEG)), ad.master.mount_sigma_deg * DEG)
        return coarse

    def make_fine(self) -> ErrorStateFilter | None:
        p = self.p
        if not p.config.fine.enabled:
            return None
        master = p.config.aiding.master
        return ErrorStateFilter(p.grade, [master_velocity(master), MasterAttitude(master.att_std_deg * DEG)],
                                p.config.fine.kalman.gate_chi2)

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """The master's velocity with the slave's gyro rate, and its attitude quaternion."""
        return [("master", "master_vel", np.r_[aid[4:7], aid[10:13]]), ("master", "master_att", aid[:4])]

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """Phase 2's prediction and matching per control step; before it, the switch from phase 1. ``aid``:
        the master's 10 values at the step's end, then the slave's gyro rate (3, rad/s)."""
        p = self.p
        C_b_b0 = dcm_from_quat(q_b_b0)
        if p.fine is None or self.kalman_step(dalpha, dt_s, C_b_b0, aid, fresh) or not np.isfinite(aid).all():
            return
        ad = p.config.aiding
        noise = p.coarse.noise_sigma(elapsed_s)
        if noise is None:
            return
        # the switch looks at the fit's noise alone (the bias floor stays until the Kalman stage separates it)
        due = elapsed_s + 1e-9 >= ad.master.handover_s if ad.master.handover_s > 0.0 else p.coarse.done(
            max(noise), elapsed_s, ad.master.handover_sigma_deg * DEG, ad.master.linear_sigma_deg * DEG)
        solution = self.handover_solution(t_end, q_b_b0, None) if due else None
        if solution is None:
            return
        # the filter's models about phase 1's mounting: the attitude matched through it, and the master's point
        # seen from the slave, in the slave's axes (its velocity is what the master reports)
        M_ref = p.coarse.mounting
        lever_b = -M_ref.T @ np.array(ad.master.lever_m)
        attitude = MasterAttitude(ad.master.att_std_deg * DEG, M_ref=M_ref)
        heading_rad, level_rad = solution.heading_sigma_deg * DEG, solution.level_sigma_deg * DEG
        C_b_n = dcm_from_quat(aid[:4]) @ M_ref         # the master's attitude now, through the mounting
        position = np.r_[np.radians(aid[7:9]), aid[9]]
        V_n = aid[4:7] - antenna_lever_velocity(C_b_n, aid[10:13], position[0], lever_b)
        p.fine.start(C_b_n, C_b_b0, V_n, position, level_rad, heading_rad,
                     HANDOVER_SIGMA_FACTOR * ad.master.vel_std_mps, velocity_from_attitude=False,
                     measurements=[master_velocity(ad.master, lever_b), attitude])
        # the φ, μ and ∇ prior: it replaces start's diagonal one
        correlate_handover(p.fine, C_b_n, *noise, p.grade, p.site.gravity)

    def mounting(self, coarse: MasterCoarseAlignment | None = None) -> tuple[np.ndarray, float]:
        """(C_bs^bm (3, 3), its 1-sigma in degrees, the largest axis): phase 2's once it runs, else phase 1's
        (of ``coarse``, the pipeline's own by default, or a scratch copy run ahead)."""
        p = self.p
        if p.fine is not None and p.fine.active:
            attitude: MasterAttitude = p.fine.measurements["master_att"]
            mu = p.fine.extra_slice("master_att")
            sigma = float(np.sqrt(np.max(np.diag(p.fine.P)[mu]))) / DEG
            return attitude.mounting(p.fine.x[mu]), sigma
        coarse = coarse or p.coarse
        nominal, nominal_sigma = coarse.best_mounting()
        if nominal_sigma is not None:
            return nominal, nominal_sigma / DEG
        sigma = coarse.fit_sigma_rad()
        return coarse.mounting, SIGMA_UNKNOWN_DEG if sigma is None else min(sigma / DEG, SIGMA_UNKNOWN_DEG)

    def record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
               coarse: InertialCoarseAlignment) -> ResultRecord:
        record = super().record(t_epoch, t_sample, q_b_b0, coarse)
        M, sigma = self.mounting(coarse)
        q = quat_from_dcm(M)
        return replace(record, mount_q=tuple(float(c) for c in q / np.linalg.norm(q)), mount_sigma_deg=sigma)


MODE = Transfer
"""The mode this module declares (:data:`~service.modes.MODES`)."""
