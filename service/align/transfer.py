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

from .conventions import dcm_from_quat, quat_from_dcm, rotvec_from_quat
from .earth import Site
from .gnss_aided import GnssVelocitySource

MASTER_COLUMNS = 10
"""qw, qx, qy, qz (the master's C_bm^n), vE, vN, vU, lat_deg, lon_deg, h_m (the pinned log's columns after t)."""
VELOCITY_GROUP, ATTITUDE_GROUP = 0, 1


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
