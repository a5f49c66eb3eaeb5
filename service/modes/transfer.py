"""Transfer alignment of a slave IMU against a master INS (seed 002, dual model): the master's quaternion of
C_bm^n, V^n ENU m/s, lat_deg, lon_deg, h_m (10 aiding values per sample), the slave's gyro rate appended.

Phase 1 (``coarse``) is the inertial-frame stage with the master source (service/align/transfer.py): velocity and
attitude pairs r = M b solved in closed form for the mounting M = C_bs^bm, whatever its size. Phase 2 (``fine`` →
``aligned``) is the error-state Kalman filter with velocity matching (the master's velocity, with the lever arm as
states) and attitude matching (the mounting as states), from the first control step at which phase 1's σ is within
``aiding.master.handover_sigma_deg``, or at ``aiding.master.handover_s`` (the seed's fixed 10 s), or within the
filter's linear range and no longer improving (a MEMS slave). It starts at the first kept master epoch about phase
1's mounting and runs over the steps since (:meth:`Transfer._catch_up`). The slave's attitude is the output; every
record carries the mounting with its σ (:meth:`Transfer.mounting`).
"""
from __future__ import annotations

from collections import deque
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ...protocol.results import ResultRecord
from ..align.coarse import InertialCoarseAlignment
from ..align.conventions import DEG, dcm_from_euler, dcm_from_quat, quat_from_dcm
from ..align.datasheet_bank import DatasheetBank
from ..align.kalman import GnssVelocity, LeverVelocity, MasterAttitude, antenna_lever_velocity
from ..align.sensor_model import SIGMA_UNKNOWN_DEG
from ..align.solvers import GroupedWahba
from ..align.transfer import (
    MASTER_COLUMNS,
    MasterCoarseAlignment,
    MasterSource,
    linear_range_rad,
    mounting_prior,
)
from .kalman import KalmanMode

if TYPE_CHECKING:
    from ..config import MasterConfig
    from ..pipeline import AlignmentPipeline

HANDOVER_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n from one master epoch: its σ is this many times the stated noise."""
BACKLOG_S = 60.0
"""A stalled phase 1's Kalman stage catches up on at most this much of its time (s)."""


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

    def make_fine(self) -> DatasheetBank | None:
        master = self.p.config.aiding.master
        return self.filter_bank(lambda: [master_velocity(master), MasterAttitude(master.att_std_deg * DEG)])

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """The master's velocity with the slave's gyro rate, and its attitude quaternion."""
        return [("master", "master_vel", np.r_[aid[4:7], aid[10:13]]), ("master", "master_att", aid[:4])]

    def __init__(self, pipeline: AlignmentPipeline) -> None:
        super().__init__(pipeline)
        self._backlog: deque[tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray, float]] = deque()

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """Phase 2's prediction and matching per control step; before it, the steps since the first master epoch
        are kept and the switch from phase 1 is checked. ``aid``: the master's 10 values at the step's end, then the
        slave's gyro rate (3, rad/s)."""
        p = self.p
        C_b_b0 = dcm_from_quat(q_b_b0)
        if p.fine is None or aid is None or self.kalman_step(dalpha, dt_s, C_b_b0, aid, fresh):
            return
        epoch = bool(np.isfinite(aid).all())
        if self._backlog or epoch:
            self._keep(q_b_b0, dalpha, dt_s, aid, fresh, elapsed_s)
        if not epoch:
            return
        ad = p.config.aiding
        noise = p.coarse.noise_sigma(elapsed_s)
        if noise is None:
            return
        # the switch looks at the fit's noise alone (the bias floor stays until the Kalman stage separates it)
        if ad.master.handover_s > 0.0:
            due = elapsed_s + 1e-9 >= ad.master.handover_s
        else:
            due = p.coarse.handover(max(noise), elapsed_s, ad.master.handover_sigma_deg * DEG, self.linear_range_rad())
        solution = self.handover_solution(t_end, q_b_b0, None) if due else None
        if solution is None:
            return
        # the prior must hold phase 1's whole error (its σ, the accelerometer bias's tilt in it) and the filter's
        # linear range: a perfect master's range alone (0.01°) left 0.3° errors at σ 0.015°
        self._catch_up(max(self.linear_range_rad(), solution.heading_sigma_deg * DEG, solution.level_sigma_deg * DEG))

    def linear_range_rad(self) -> float:
        """The linear range (rad) of the filter's models: ``aiding.master.linear_sigma_deg`` or the master's
        noise's (:func:`~..align.transfer.linear_range_rad`), the smaller."""
        master = self.p.config.aiding.master
        return min(master.linear_sigma_deg * DEG, linear_range_rad(master.att_std_deg * DEG))

    def _keep(self, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float, aid: np.ndarray, fresh: np.ndarray,
              elapsed_s: float) -> None:
        """Keep a step for :meth:`_catch_up`: at most :data:`BACKLOG_S` of them, the oldest with a master epoch."""
        backlog = self._backlog
        backlog.append((q_b_b0.copy(), np.array(dalpha, dtype=float), dt_s, aid.copy(), fresh.copy(), elapsed_s))
        while backlog and (elapsed_s - backlog[0][5] > BACKLOG_S or not np.isfinite(backlog[0][3]).all()):
            backlog.popleft()

    def _start(self, fine: DatasheetBank, aid: np.ndarray, C_b_b0: np.ndarray, level_rad: float,
               heading_rad: float, M_ref: np.ndarray) -> np.ndarray:
        """Start ``fine`` at a master epoch (``aid``, body attitude C_b^{b0}) about the mounting ``M_ref``; C_bs^n
        there."""
        master = self.p.config.aiding.master
        # the filter's models about that mounting: the attitude matched through it, and the master's point seen
        # from the slave, in the slave's axes (its velocity is what the master reports)
        lever_b = -M_ref.T @ np.array(master.lever_m)
        attitude = MasterAttitude(master.att_std_deg * DEG, M_ref=M_ref)
        C_b_n = dcm_from_quat(aid[:4]) @ M_ref         # the master's attitude then, through the mounting
        position = np.r_[np.radians(aid[7:9]), aid[9]]
        V_n = aid[4:7] - antenna_lever_velocity(C_b_n, aid[10:13], position[0], lever_b)
        fine.start(C_b_n, C_b_b0, V_n, position, level_rad, heading_rad, HANDOVER_SIGMA_FACTOR * master.vel_std_mps,
                   velocity_from_attitude=False, measurements=[master_velocity(master, lever_b), attitude])
        return C_b_n

    def _catch_up(self, sigma_rad: float) -> None:
        """Phase 1 hands over its mounting only: the filter starts at the oldest kept master epoch, linearised about
        that mounting with a prior that holds nothing of the data (:func:`mounting_prior`, 1-sigma ``sigma_rad``
        per axis), and runs over every step since, its bias states modelling the slave's biases from the start.
        Started from phase 1's answer instead, it inherited a fit that takes the accelerometer bias for a tilt and
        weighs the velocity pairs by the slave's whole datasheet bias integrated since the start: a good slave's
        level 0.36° off at 10 s (0.04° so), a MEMS slave's heading σ at 4-9 times the Cramér-Rao bound of the data
        driving straight."""
        p = self.p
        (q_b_b0, _, _, aid, _, _), *steps = self._backlog
        mounting_prior(p.fine, self._start(p.fine, aid, dcm_from_quat(q_b_b0), sigma_rad, sigma_rad,
                                           p.coarse.mounting), sigma_rad)
        for q_b_b0, dalpha, dt_s, aid, fresh, _ in steps:
            self.fold(p.fine, dalpha, dt_s, dcm_from_quat(q_b_b0), aid, fresh)
        self._backlog.clear()

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
