"""The transfer-alignment pipeline (seed 002, dual model): the same pipeline, other parts.

Phase 1 (``coarse``) is the core's inertial-frame stage with the master source
(service/align/transfer.py): velocity and attitude pairs r = M b solved in closed form for the
mounting M = C_bs^bm, whatever its size. Phase 2 (``fine`` → ``aligned``) is the same error-state
Kalman filter as the other aided modes, with velocity matching (the master's velocity, a fix of the
GNSS velocity's form) and attitude matching (:class:`~.align.kalman.MasterAttitude`, the mounting
as extra states, and the lever arm), from the first control step at which phase 1's σ is within
``aiding.master_handover_sigma_deg``, or within ``aiding.master_linear_sigma_deg`` (the filter's linear range)
and no longer improving (a MEMS slave), or at ``aiding.master_handover_s`` (the seed's fixed 10 s).
The slave's attitude is the output; :meth:`TransferPipeline.mounting` gives M with its σ.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..protocol.results import ResultRecord
from .align.coarse import InertialCoarseAlignment
from .align.conventions import DEG, dcm_from_euler, dcm_from_quat, quat_from_dcm
from .align.kalman import (
    ACC_BIAS,
    PHI,
    ErrorStateFilter,
    GnssVelocity,
    LeverVelocity,
    MasterAttitude,
    antenna_lever_velocity,
)
from .align.sensor_model import SIGMA_UNKNOWN_DEG
from .align.solvers import GroupedWahba
from .align.transfer import MASTER_COLUMNS, MasterSource
from .kalman_stage import GyroRateAidPipeline

PHASE1_SIGMA_FACTOR = 2.5
"""The fit's σ assumes white residuals; the pairs' errors are integrated biases. Seed-002 Monte Carlo (20
seeds, phase 1 until 10 s): |heading error|/σ had 90th percentile 2.8 and maximum 3.8 at 1.5; at 2.5, 1.7
and 2.3."""
LINEAR_LIMIT_DEG = 10.0
"""A phase-1 heading σ above this is reported as unknown: the covariance is a linearisation about the estimate."""
PHASE1_STALL_S = 2.0
"""Phase 1 has done what it can once its noise σ has not improved for this long (s): with a poor slave it bottoms
out within seconds and then grows with the gyro drift."""
HANDOVER_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n from one master epoch: its σ is this many times the stated noise."""


class MasterCoarseAlignment(InertialCoarseAlignment):
    """Phase 1: the grouped solver's estimate is the mounting M; the attitude is X = P_f M S_fᵀ (C_bs0^{n0})."""

    source: MasterSource

    def observe(self, elapsed_s: np.ndarray, q_b_b0: np.ndarray, alpha: np.ndarray, aid: np.ndarray | None = None,
                aid_epoch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.source.mounting_estimate = self.mounting     # the lever arm in the slave's axes
        self.source.follow(elapsed_s, aid)
        due, outer, pairs = super().observe(elapsed_s, q_b_b0, alpha, aid, aid_epoch)
        return np.repeat(due, 2), outer, pairs            # two pairs per epoch

    def prepare_pairs(self, elapsed_s: np.ndarray, b: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.solver.prepare(b, r, self.source.observation_variance(elapsed_s),
                                   self.source.pair_groups(len(elapsed_s)))

    nominal: tuple[np.ndarray, float] | None = None
    """A rough nominal mounting C_bs^bm (3, 3) and its 1-sigma (rad), if configured: the answer until the fit's."""

    @property
    def mounting(self) -> np.ndarray:
        """The estimate of C_bs^bm (3, 3)."""
        return dcm_from_quat(self.solver.quaternion())

    _covariance: tuple[int, np.ndarray | None] = (-1, None)

    def fit_covariance(self) -> np.ndarray | None:
        """The grouped fit's covariance (3, 3) rad² of the mounting, in the master's axes (None before it has one):
        computed once per number of pairs folded (σ, the switch, the records and the mounting all ask)."""
        if self._covariance[0] != self.solver.n_obs:
            self._covariance = (self.solver.n_obs, self.solver.covariance())
        return self._covariance[1]

    def fit_sigma_rad(self) -> float | None:
        """The reported 1-sigma (rad) of the fit's mounting, its largest axis; None before the fit has a covariance."""
        covariance = self.fit_covariance()
        return None if covariance is None else PHASE1_SIGMA_FACTOR * float(np.sqrt(np.max(np.diag(covariance))))

    @property
    def resolved(self) -> bool:
        """Whether the fit has fixed every axis of the mounting (its heading σ within :data:`LINEAR_LIMIT_DEG`)."""
        sigma = self.fit_sigma_rad()
        return sigma is not None and sigma <= LINEAR_LIMIT_DEG * DEG

    _best_noise: tuple[float, float] = (np.inf, 0.0)

    def done(self, noise_rad: float, elapsed_s: float, precise_rad: float, linear_rad: float) -> bool:
        """Whether phase 1 has done what it can, given its noise σ now (rad, the larger of heading and level): within
        ``precise_rad``, or within ``linear_rad`` (the Kalman stage's linear range, where it takes the errors over
        with their correlations) and no better than :data:`PHASE1_STALL_S` ago. A good slave reaches the first; a
        MEMS slave's σ bottoms out at degrees and then grows with its drift, and only the Kalman stage can estimate
        the biases that cause it."""
        if noise_rad < self._best_noise[0]:
            self._best_noise = (noise_rad, elapsed_s)
        return noise_rad <= precise_rad or (noise_rad <= linear_rad
                                            and elapsed_s - self._best_noise[1] >= PHASE1_STALL_S)

    def best_mounting(self) -> tuple[np.ndarray, float | None]:
        """(C_bs^bm, its 1-sigma in rad if it is the nominal one): the fit's once resolved, else the nominal."""
        if self.nominal is not None and not self.resolved:
            return self.nominal
        return self.mounting, None

    @property
    def q_b_n0(self) -> np.ndarray:
        return quat_from_dcm(self.source.C_b0_n0(self.best_mounting()[0]))

    def noise_sigma(self, elapsed_s: float) -> tuple[float, float] | None:
        """1-sigma (heading, level) in rad of the slave's attitude from the fit's noise alone: the mounting's
        covariance in the master's axes turned into n0, and the slave's gyro drift since the start; None
        before the fit has residual degrees of freedom."""
        covariance = self.fit_covariance()
        if covariance is None:
            return None
        P = self.source.P_first
        covariance = PHASE1_SIGMA_FACTOR**2 * (P @ covariance @ P.T)
        drift2 = (self.grade.gyro_bias_rad_s * max(elapsed_s, 0.0)) ** 2
        return float(np.sqrt(covariance[2, 2] + drift2)), float(np.sqrt(0.5 * (covariance[0, 0] + covariance[1, 1])
                                                                         + drift2))

    def sigma(self, elapsed_s: float) -> tuple[float, float]:
        """1-sigma (heading, level) in degrees: the noise part, and in level the accelerometer bias's tilt ∇/g
        (the velocity pairs cannot tell a bias from a tilt; the Kalman stage can, once the body rolls)."""
        nominal_sigma = self.best_mounting()[1]
        if nominal_sigma is not None:
            drift = self.grade.gyro_bias_rad_s * max(elapsed_s, 0.0)
            return (min(float(np.hypot(nominal_sigma, drift)) / DEG, SIGMA_UNKNOWN_DEG),) * 2
        noise = self.noise_sigma(elapsed_s)
        if noise is None:
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        heading, level = noise
        level = np.hypot(level, self.grade.acc_bias_ms2 / self.source.site.gravity)
        # beyond ~10° the fit's linearised covariance means nothing (before the first roll: 170° off at σ 18°)
        heading = SIGMA_UNKNOWN_DEG * DEG if heading > LINEAR_LIMIT_DEG * DEG else heading
        return min(heading / DEG, SIGMA_UNKNOWN_DEG), min(float(level) / DEG, SIGMA_UNKNOWN_DEG)


class TransferPipeline(GyroRateAidPipeline):
    """Transfer alignment of a slave IMU against a master INS (10 aiding values per sample: the master's
    quaternion of C_bm^n, V^n ENU m/s, lat_deg, lon_deg, h_m)."""

    aid_width = MASTER_COLUMNS
    aid_kind = "master"
    checks_translation = False
    handover_limit_key = "master_linear_sigma_deg"

    def _make_coarse(self) -> InertialCoarseAlignment:
        a, ad = self.config.alignment, self.config.aiding
        source = MasterSource(self.site, ad.master_att_std_deg * DEG, ad.master_vel_std_mps, self.grade.gyro_bias_rad_s,
                              self.grade.acc_bias_ms2, np.array(ad.master_lever_m))
        coarse = MasterCoarseAlignment(source, self.grade, GroupedWahba(2), self.sample_period_s, a.obs_interval_s,
                                       a.disturbance_velocity_mps)
        if ad.master_mount_deg:
            coarse.nominal = (dcm_from_euler(*(np.array(ad.master_mount_deg) * DEG)), ad.master_mount_sigma_deg * DEG)
        return coarse

    def _make_fine(self) -> ErrorStateFilter | None:
        if not self.config.fine.enabled:
            return None
        ad = self.config.aiding
        velocity = (LeverVelocity(ad.master_vel_std_mps, lever_sigma_m=ad.master_lever_sigma_m, name="master_vel")
                    if ad.master_lever_sigma_m > 0.0 else GnssVelocity(ad.master_vel_std_mps, name="master_vel"))
        return ErrorStateFilter(self.grade, [velocity, MasterAttitude(ad.master_att_std_deg * DEG)], ad.gate_chi2)

    def _measurements(self, aid: np.ndarray) -> list[tuple[str, np.ndarray]]:
        """The master's velocity with the slave's gyro rate, and its attitude quaternion."""
        return [("master_vel", np.r_[aid[4:7], aid[10:13]]), ("master_att", aid[:4])]

    def _stage_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray,
                    dt_s: float, aid: np.ndarray | None, fresh: bool) -> None:
        """Phase 2's prediction and matching per control step; before it, the switch from phase 1. ``aid``:
        the master's 10 values at the step's end, then the slave's gyro rate (3, rad/s)."""
        C_b_b0 = dcm_from_quat(q_b_b0)
        if self.fine is None or self._kalman_step(dalpha, dt_s, C_b_b0, aid, fresh) or not np.isfinite(aid).all():
            return
        ad = self.config.aiding
        noise = self.coarse.noise_sigma(elapsed_s)
        if noise is None:
            return
        # the switch looks at the fit's noise alone (the bias floor stays until the Kalman stage separates it)
        due = elapsed_s + 1e-9 >= ad.master_handover_s if ad.master_handover_s > 0.0 else self.coarse.done(
            max(noise), elapsed_s, ad.master_handover_sigma_deg * DEG, ad.master_linear_sigma_deg * DEG)
        solution = self._handover_solution(t_end, q_b_b0, None) if due else None
        if solution is None:
            return
        attitude: MasterAttitude = self.fine.measurements["master_att"]
        attitude.M_ref = self.coarse.mounting
        # the master's point from the slave, in the slave's axes: its velocity is what the master reports
        velocity: GnssVelocity = self.fine.measurements["master_vel"]
        velocity.lever_b = -attitude.M_ref.T @ np.array(ad.master_lever_m)
        heading_rad, level_rad = solution.heading_sigma_deg * DEG, solution.level_sigma_deg * DEG
        C_b_n = dcm_from_quat(aid[:4]) @ attitude.M_ref         # the master's attitude now, through the mounting
        position = np.r_[np.radians(aid[7:9]), aid[9]]
        V_n = aid[4:7] - antenna_lever_velocity(C_b_n, aid[10:13], position[0], velocity.lever_b)
        self.fine.start(C_b_n, C_b_b0, V_n, position, level_rad, heading_rad,
                        HANDOVER_SIGMA_FACTOR * ad.master_vel_std_mps, velocity_from_attitude=False)
        self._correlate_handover(C_b_n, *noise)   # the φ, μ and ∇ prior: it replaces start's diagonal one

    def _correlate_handover(self, C_b_n: np.ndarray, heading_noise_rad: float, level_noise_rad: float) -> None:
        """Phase 1's errors as the filter must start with them: one error, three views.

        The slave's attitude is the master's through M_ref, so its error φ = C_bs^n μ is the mounting's μ seen in
        n axes (attitude matching alone cannot tell them apart: its innovation φ + C_bs^n (μ̂ − μ) starts at 0).
        And the velocity pairs hid the accelerometer bias ∇ as a tilt, f^n × φ = −C_bs^n ∇ horizontally:
        φ_E = −(C∇)_N / g, φ_N = (C∇)_E / g. So φ = A ∇ + n (n: the fit's noise), μ = C_bs^nᵀ φ, and the covariance
        of (φ, μ, ∇) is J Σ Jᵀ with Σ of (∇, n). Started uncorrelated, the filter took the first velocity misfit
        for a tilt and the first attitude misfit for a slave error: 8σ heading and 4σ level errors at 1-5 s.
        """
        f, g = self.fine, self.site.gravity
        A = np.array([[0.0, -1.0 / g, 0.0], [1.0 / g, 0.0, 0.0], [0.0, 0.0, 0.0]]) @ C_b_n
        mu = f.extra_slice("master_att")
        J = np.zeros((f.n_states, 6))
        J[PHI, :3], J[PHI, 3:] = A, np.eye(3)
        J[mu, :3], J[mu, 3:] = C_b_n.T @ A, C_b_n.T
        J[ACC_BIAS, :3] = np.eye(3)
        # the tilt may also be free of ∇: once the body has rolled, phase 1 has partly told them apart
        level_rad = np.hypot(level_noise_rad, self.grade.acc_bias_ms2 / g)
        Sigma = np.diag([self.grade.acc_bias_ms2**2] * 3 + [level_rad**2] * 2 + [heading_noise_rad**2])
        states = np.r_[np.arange(PHI.start, PHI.stop), np.arange(mu.start, mu.stop),
                       np.arange(ACC_BIAS.start, ACC_BIAS.stop)]
        block = (J @ Sigma @ J.T)[np.ix_(states, states)]
        # the master's own attitude noise on top of the slave's attitude error
        block[:3, :3] += np.eye(3) * self.fine.measurements["master_att"].std_rad ** 2
        f.P[np.ix_(states, states)] = block

    def mounting(self, coarse: MasterCoarseAlignment | None = None) -> tuple[np.ndarray, float]:
        """(C_bs^bm (3, 3), its 1-sigma in degrees, the largest axis): phase 2's once it runs, else phase 1's
        (of ``coarse``, the pipeline's own by default, or a scratch copy run ahead)."""
        if self.fine is not None and self.fine.active:
            attitude: MasterAttitude = self.fine.measurements["master_att"]
            mu = self.fine.extra_slice("master_att")
            sigma = float(np.sqrt(np.max(np.diag(self.fine.P)[mu]))) / DEG
            return attitude.mounting(self.fine.x[mu]), sigma
        coarse = coarse or self.coarse
        nominal, nominal_sigma = coarse.best_mounting()
        if nominal_sigma is not None:
            return nominal, nominal_sigma / DEG
        sigma = coarse.fit_sigma_rad()
        return coarse.mounting, SIGMA_UNKNOWN_DEG if sigma is None else min(sigma / DEG, SIGMA_UNKNOWN_DEG)

    def _stage_record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
                      coarse: InertialCoarseAlignment) -> ResultRecord:
        record = super()._stage_record(t_epoch, t_sample, q_b_b0, coarse)
        M, sigma = self.mounting(coarse)
        q = quat_from_dcm(M)
        return replace(record, mount_q=tuple(float(c) for c in q / np.linalg.norm(q)), mount_sigma_deg=sigma)
