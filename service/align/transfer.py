"""Transfer alignment against a master INS (seed 002, docs/algorithms/transfer.md): the large-angle phase 1.

The unknown is the mounting M = C_bs^bm (slave to master body axes), of any size. Let n0 be the
navigation frame at the first master epoch t_f frozen in inertial space (as the GNSS sources'),
P(t) = C_{n(t)}^{n0} C_bm^n(t) the master's body attitude in it, S(t) = C_bs^{bs0}(t) the slave's
from its own gyros, and X = C_bs0^{n0} the slave's initial attitude: X S(t) = P(t) M. Two kinds of
vector pairs follow, each of the form r = M b:

- attitude: A_k M = M B_k with A_k = P_fᵀ P_k (the master's rotation since t_f, its first body axes)
  and B_k = S_fᵀ S_k (the slave's), so rotvec(A_k) = M rotvec(B_k). Rotations about two axes fix M;
  a wing rock gives one;
- velocity: the velocity integration formula X α_v = β_v (the GNSS VIF source, on the master's
  velocity and position) gives P_fᵀ β_v = M S_fᵀ α_v: gravity's reaction supplies the second axis.

The solver (:class:`~.solvers.GroupedWahba`) adds the two groups' losses, each pair weighted by its
stated noise: the master's (attitude, velocity) plus what the slave's datasheet biases integrate to
since t_f (gyro bias × T, accelerometer bias × T), so the early pairs lead. No linearisation: any
mounting, 120° as well as 20°. Then X = P_f M S_fᵀ and the slave's attitude is C_n^{n0}(t)ᵀ X S(t).
"""
from __future__ import annotations

import copy

import numpy as np

from .coarse import InertialCoarseAlignment
from .conventions import DEG, dcm_from_quat, quat_from_dcm, rotvec_from_quat
from .earth import Site
from .gnss_aided import GnssVelocitySource
from .kalman import PHI, ErrorStateFilter
from .sensor_model import SIGMA_UNKNOWN_DEG

MASTER_COLUMNS = 10
"""qw, qx, qy, qz (the master's C_bm^n), vE, vN, vU, lat_deg, lon_deg, h_m (the pinned log's columns after t)."""
VELOCITY_GROUP, ATTITUDE_GROUP = 0, 1
PHASE1_SIGMA_FACTOR = 2.5
"""The fit's σ assumes white residuals; the pairs' errors are integrated biases. Seed-002 Monte Carlo (20
seeds, phase 1 until 10 s): |heading error|/σ had 90th percentile 2.8 and maximum 3.8 at 1.5; at 2.5, 1.7
and 2.3."""
LINEAR_LIMIT_DEG = 10.0
"""A phase-1 heading σ above this is reported as unknown: the covariance is a linearisation about the estimate."""
PHASE1_STALL_S = 0.5
"""Phase 1 has done what it can once its noise σ has not improved for this long (s): with a poor slave it bottoms
out within seconds and then grows with the gyro drift. The Kalman stage then runs over the data from the start, so
an early stall loses nothing (``transfer-mems``, 20 seeds: the same worst figures at 0.5 s as at 2 s, the filter's
σ reached seconds sooner)."""


class MasterSource:
    """Observation source of phase 1: per master epoch a velocity pair and an attitude pair, interleaved
    (:meth:`pair_groups` says which is which), both r = M b (module docstring).

    site : start position. att_std_rad, vel_std_mps : the master's white noise per axis.
    gyro_bias_rad_s, acc_bias_ms2 : the slave's datasheet biases (how fast its pairs lose weight).
    lever_m : from the master's point to the slave IMU, master body axes (m). The velocity pairs see the
        master's point, at −Mᵀ l from the slave in its own axes: the VIF source's lever arm, with M the
        latest estimate (:attr:`mounting_estimate`, set by the coarse stage before each batch).
    """

    aid_width = MASTER_COLUMNS

    def __init__(self, site: Site, att_std_rad: float, vel_std_mps: float, gyro_bias_rad_s: float,
                 acc_bias_ms2: float, lever_m: np.ndarray | None = None) -> None:
        self.site = site
        self.att_std_rad = att_std_rad
        self.vel_std_mps = vel_std_mps
        self.gyro_bias_rad_s = gyro_bias_rad_s
        self.acc_bias_ms2 = acc_bias_ms2
        self.velocity = GnssVelocitySource(site, None, vel_std_mps)
        self.lever_m = np.zeros(3) if lever_m is None else np.asarray(lever_m, dtype=float)
        self.mounting_estimate = np.eye(3)
        self._P_first: np.ndarray | None = None
        self._S_first = np.eye(3)

    def __copy__(self) -> MasterSource:
        clone = object.__new__(MasterSource)
        clone.__dict__.update(self.__dict__)
        clone.velocity = copy.copy(self.velocity)
        return clone

    @staticmethod
    def _gnss_columns(aid: np.ndarray) -> np.ndarray:
        """The master's position and velocity, and the slave's gyro rate, in the VIF source's aid columns."""
        return np.column_stack((aid[:, 7:10], aid[:, 4:7], aid[:, 10:13]))

    def follow(self, elapsed_s: np.ndarray, aid: np.ndarray) -> None:
        """The master's positions at every integrated sample (:meth:`GnssSource.follow`)."""
        self.velocity.follow(elapsed_s, self._gnss_columns(aid))

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(b (2M, 3), r (2M, 3)): at each of M epochs the velocity pair (m/s) then the attitude pair (rad);
        b in the slave's body axes at t_f, r in the master's. ``aid`` (M, 13): the master's ten values, then the
        slave's gyro rate ω_ib^bs (3, rad/s)."""
        if aid is None:
            raise ValueError("transfer alignment needs the master's output at every observation")
        if len(elapsed_s) == 0:
            return np.empty((0, 3)), np.empty((0, 3))
        self.velocity.lever_b = -self.mounting_estimate.T @ self.lever_m
        b_v, r_v = self.velocity.vectors(elapsed_s, alpha_b0, q_b_b0, self._gnss_columns(aid))
        lat, lon = np.radians(aid[:, 7]), np.radians(aid[:, 8])
        P = self.velocity.C_n_n0_at(elapsed_s, lat, lon) @ dcm_from_quat(aid[:, :4])
        S = dcm_from_quat(q_b_b0)
        if self._P_first is None:
            self._P_first, self._S_first = P[0].copy(), S[0].copy()
        b_a = rotvec_from_quat(quat_from_dcm(self._S_first.T @ S))
        r_a = rotvec_from_quat(quat_from_dcm(self._P_first.T @ P))
        # rows: S_fᵀ b_v. einsum, not a BLAS product, whose last bits depend on how many rows a call has: the
        # pairs must be the same bits live (a few rows a call) as in one chunk
        b = np.stack((np.einsum("ij,jk->ik", b_v, self._S_first), b_a), axis=1).reshape(-1, 3)
        r = np.stack((np.einsum("ij,jk->ik", r_v, self._P_first), r_a), axis=1).reshape(-1, 3)
        return b, r

    def observation_variance(self, elapsed_s: np.ndarray) -> np.ndarray:
        """μ (2M,) per axis, interleaved as the pairs: velocity (m²/s²) and attitude (rad²), the master's noise
        plus the slave's biases integrated since t_f."""
        span = self.velocity.span_s(elapsed_s)
        velocity = self.vel_std_mps**2 + (self.acc_bias_ms2 * span) ** 2
        attitude = 2.0 * self.att_std_rad**2 + (self.gyro_bias_rad_s * span) ** 2
        return np.stack((velocity, attitude), axis=1).reshape(-1)

    @staticmethod
    def pair_groups(n_epochs: int) -> np.ndarray:
        return np.tile([VELOCITY_GROUP, ATTITUDE_GROUP], n_epochs)

    def C_b0_n0(self, C_bs_bm: np.ndarray) -> np.ndarray:
        """X = C_bs0^{n0} = P_f M S_fᵀ of a mounting estimate M (the identity before the first epoch)."""
        if self._P_first is None:
            return np.eye(3)
        return self._P_first @ C_bs_bm @ self._S_first.T

    @property
    def P_first(self) -> np.ndarray:
        """C_bm^{n0} at the first master epoch (the identity before it)."""
        return np.eye(3) if self._P_first is None else self._P_first

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        return self.velocity.C_n_n0(elapsed_s)


class MasterCoarseAlignment(InertialCoarseAlignment):
    """Phase 1: the grouped solver's estimate is the mounting M; the attitude is X = P_f M S_fᵀ (C_bs0^{n0})."""

    follows_aid = True   # its source follows the aid at every sample (positions, integrals)

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

    def handover(self, noise_rad: float, elapsed_s: float, precise_rad: float, linear_rad: float) -> bool:
        """Whether phase 1 has done what it can, given its noise σ now (rad, the larger of heading and level): it is
        within ``precise_rad`` (a good slave), or within ``linear_rad`` (the Kalman stage's linear range) and no
        better than :data:`PHASE1_STALL_S` ago (stalled: a MEMS slave's σ bottoms out at degrees and then grows with
        its drift, and only the Kalman stage, run over the data from the start (:func:`mounting_prior`), can estimate
        the biases that cause it)."""
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


def linear_range_rad(att_std_rad: float) -> float:
    """The largest phase-1 σ (rad) the Kalman stage can be linearised about, for a master of attitude noise
    ``att_std_rad``. Attitude matching composes the slave's error with the mounting's; what the filter's linear
    model leaves out is their product, about σ²/2, which must stay within the master's noise or the first updates
    pull the estimate off by more than the filter's σ: 4.1° for a 0.15° master (flexure, vibration), 0.34° for a
    0.001° one."""
    return float(np.sqrt(2.0 * att_std_rad))


def mounting_prior(f: ErrorStateFilter, C_b_n: np.ndarray, sigma_rad: float) -> None:
    """The filter's prior at the first master epoch, before it has seen any data (it is then run over them): the
    mounting's error μ of 1-sigma ``sigma_rad`` per axis about phase 1's mounting, and the slave's attitude error the
    same error seen in n axes, φ = C_bs^n μ (the slave's attitude is the master's through the mounting), plus the
    master's own attitude noise on φ. Nothing of the data is in it, so nothing is counted twice."""
    mu = f.extra_slice("master_att")
    J = np.vstack((C_b_n, np.eye(3)))
    block = sigma_rad**2 * (J @ J.T)
    block[:3, :3] += np.eye(3) * f.measurements["master_att"].std_rad ** 2
    f.set_covariance(np.r_[np.arange(PHI.start, PHI.stop), np.arange(mu.start, mu.stop)], block)
