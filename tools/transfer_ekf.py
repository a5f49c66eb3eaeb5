"""The seed's phase 1 of transfer alignment (seed 002): an extended Kalman filter on the additive quaternion
error model with quaternion matching (docs/algorithms/transfer.md, "Phase 1 against the seed's own"). A
comparison baseline for the closed-form phase 1 (:mod:`.transfer`); offline (whole arrays in, a history out),
pure numpy, float64.

Frames and units (docs/algorithms/conventions.md): n is ENU, the bodies are RFU; bs is the slave IMU's body, bm the
master's. q_bs_n = [w, x, y, z] is the slave's attitude C_bs^n, q_bs_bm the mounting M = C_bs^bm, so the
master's attitude is q_bm_n = q_bs_n ⊗ q_bs_bm*. Rates rad/s, velocity ENU m/s, time s.

The seed's model (its eq. (2)) keeps the quaternion's four components as states and its error as an
additive δq = q̂ − q: the attitude equation q̇ = ½ (q ⊗ ω_ib^b − ω_in^n ⊗ q) is linear in q, so δq obeys the
same equation (the seed's matrix M) plus ½ q ⊗ ε (its U), and the velocity error carries the quadratic
term of q ⊗ f ⊗ q* (its Yᵀ U f). Written as a full-state EKF on the components, that is exactly the
additive model, with Jacobians from the quaternion products (no small-angle assumption on the attitude):

states x = [q_bs_n (4), V^n (3), gyro bias ε (3, rad/s, bs axes), accelerometer bias ∇ (3, m/s², bs axes),
q_bs_bm (4)],

  q ← r_n* ⊗ q ⊗ Δq_b ⊗ exp(−ε Δt)            (r_n = exp(ω_in^n Δt / 2): the n frame's turn over the step)
  V ← V + C(q_mid) (Δv_b − ∇ Δt) + (g^n − (2ω_ie^n + ω_en^n) × V) Δt

with Δq_b and Δv_b the slave's body rotation and velocity increment over the step from its own samples
(:class:`~.strapdown.InertialIntegrator`, coning and sculling corrected), in the step's first body axes.

Measurements at each master epoch: the master's quaternion, h = q_bs_n ⊗ q_bs_bm* (the quaternion
matching of the seed's phase 1), and the master's velocity, h = V^n. In the seed the mounting is known
and the quaternion alone gives the slave's attitude. Here the mounting is unknown, so it is a state, the
last four, also additive. The quaternion then fixes the mounting only through the body's rotations: a
wing rock about one axis leaves the rotation about that axis free. Gravity through the velocity matching
supplies the second axis, as the closed form's velocity pairs do (``velocity_matching=False`` gives the
seed's quaternion matching alone). Both quaternions are renormalised after every update and their
covariance is projected onto the unit sphere's tangent (the norm is not an error).

Start: at the first master epoch, with the mounting assumed to be the identity (q_bs_n = the master's
quaternion) and a large covariance for the mounting, correlated with the slave's attitude as
q_bs_n = q_bm_n ⊗ q_bs_bm requires.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sinsalign.service.align.conventions import cross, dcm_from_quat, quat_from_rotvec, skew
from sinsalign.service.align.earth import earth_rate_n, normal_gravity, transport_rate_n
from sinsalign.service.align.sensor_model import SensorGrade
from sinsalign.service.align.strapdown import InertialIntegrator
from sinsalign.service.align.transfer import MASTER_COLUMNS

ATT, VEL, GYRO_BIAS, ACC_BIAS, MOUNT = slice(0, 4), slice(4, 7), slice(7, 10), slice(10, 13), slice(13, 17)
N_STATES = 17
CONJ = np.diag([1.0, -1.0, -1.0, -1.0])
"""q* = CONJ q."""
VECTOR = np.vstack((np.zeros(3), np.eye(3)))
"""(4, 3): the pure quaternion [0, v] = VECTOR v."""
MOUNT_SIGMA = 0.5
"""Initial 1-sigma of each of the mounting quaternion's vector components: a uniformly unknown rotation's."""
STEP_S = 0.1
"""Longest prediction step (s): the master's 10-Hz epochs."""
BIAS_INSTABILITY_FRACTION = 0.1
"""Random walk of each bias per hour, as a fraction of its 1-sigma value (as the Kalman stage's)."""


def quat_left(q: np.ndarray) -> np.ndarray:
    """L(q) (4, 4) with q ⊗ p = L(q) p."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def quat_right(q: np.ndarray) -> np.ndarray:
    """R(q) (4, 4) with p ⊗ q = R(q) p."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The vector part of q ⊗ [0, v] ⊗ q* (3,): C(q) v for a unit q, |q|² C v otherwise (the additive model's form)."""
    return (quat_left(q) @ quat_right(CONJ @ q) @ VECTOR @ v)[1:]


def rotate_jacobian(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """∂(q ⊗ [0, v] ⊗ q*)/∂q (3, 4), vector part: R([0, v] ⊗ q*) + L(q ⊗ [0, v]) CONJ."""
    pv = VECTOR @ v
    return (quat_right(quat_left(pv) @ (CONJ @ q)) + quat_left(quat_left(q) @ pv) @ CONJ)[1:]


def master_quaternion(q_bs_n: np.ndarray, q_bs_bm: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(h = q_bs_n ⊗ q_bs_bm* (4,), ∂h/∂q_bs_n (4, 4), ∂h/∂q_bs_bm (4, 4)): the master's attitude the states predict."""
    return quat_left(q_bs_n) @ (CONJ @ q_bs_bm), quat_right(CONJ @ q_bs_bm), quat_left(q_bs_n) @ CONJ


def tangent_projector(q: np.ndarray) -> np.ndarray:
    """I − q qᵀ (4, 4) of a unit q: the Jacobian of normalisation at it."""
    return np.eye(4) - np.outer(q, q)


def angle_covariance(q: np.ndarray, P_qq: np.ndarray) -> np.ndarray:
    """Covariance (3, 3, rad²) of the misalignment φ (n axes) of a quaternion estimate q of C_b^n with the
    covariance P_qq (4, 4) of its components: q̂ = exp(−φ/2) ⊗ q, so φ = −2 vec(δq ⊗ q*)."""
    G = 2.0 * quat_right(CONJ @ q)[1:]
    return G @ P_qq @ G.T


@dataclass(frozen=True, slots=True)
class EkfSettings:
    """The filter's figures. att_std_rad, vel_std_mps : the master's white noise per axis (rad, m/s).
    mount_sigma : initial 1-sigma of the mounting quaternion's vector components.
    velocity_matching : use the master's velocity too (False: quaternion matching alone, as the seed's phase 1).
    step_s : longest prediction step (s)."""

    att_std_rad: float
    vel_std_mps: float
    mount_sigma: float = MOUNT_SIGMA
    velocity_matching: bool = True
    step_s: float = STEP_S


class AdditiveQuaternionEkf:
    """The filter (module docstring): :meth:`start` at a master epoch, then :meth:`predict` per step and
    :meth:`update` per master epoch. ``grade``: the slave's datasheet (process noise, the biases' prior)."""

    def __init__(self, grade: SensorGrade, settings: EkfSettings) -> None:
        self.grade = grade
        self.settings = settings
        self.x = np.zeros(N_STATES)
        self.P = np.zeros((N_STATES, N_STATES))
        self.position = np.zeros(3)
        """lat rad, lon rad, h m: the master's latest (the slave sits at the master's point)."""

    @property
    def q_bs_n(self) -> np.ndarray:
        return self.x[ATT]

    @property
    def q_bs_bm(self) -> np.ndarray:
        return self.x[MOUNT]

    def start(self, q_bm_n: np.ndarray, V_n: np.ndarray, position: np.ndarray) -> None:
        """Start from a master epoch: its quaternion (4,), velocity (3,) m/s and position (3,); the mounting the
        identity with a large covariance, the biases zero with the datasheet's."""
        s, g = self.settings, self.grade
        q_bm_n = np.asarray(q_bm_n, dtype=float) / np.linalg.norm(q_bm_n)
        mount = np.array([1.0, 0.0, 0.0, 0.0])
        self.x = np.concatenate((q_bm_n, V_n, np.zeros(6), mount))
        self.position = np.asarray(position, dtype=float).copy()
        P_mount = s.mount_sigma**2 * tangent_projector(mount)
        L = quat_left(q_bm_n)                                   # q_bs_n = q_bm_n ⊗ q_bs_bm
        master = 0.25 * s.att_std_rad**2 * tangent_projector(q_bm_n)
        self.P = np.zeros((N_STATES, N_STATES))
        self.P[ATT, ATT] = L @ P_mount @ L.T + master
        self.P[ATT, MOUNT] = L @ P_mount
        self.P[MOUNT, ATT] = self.P[ATT, MOUNT].T
        self.P[MOUNT, MOUNT] = P_mount
        self.P[VEL, VEL] = s.vel_std_mps**2 * np.eye(3)
        self.P[GYRO_BIAS, GYRO_BIAS] = g.gyro_bias_rad_s**2 * np.eye(3)
        self.P[ACC_BIAS, ACC_BIAS] = g.acc_bias_ms2**2 * np.eye(3)

    def predict(self, dq_b: np.ndarray, dv_b: np.ndarray, dt_s: float) -> None:
        """One step: the slave's body rotation dq_b (4,) and velocity increment dv_b (3,) m/s (first body axes)
        over ``dt_s`` seconds."""
        if dt_s <= 0.0:
            return
        x = self.x
        q, V, eps, nabla = x[ATT], x[VEL], x[GYRO_BIAS], x[ACC_BIAS]
        lat, h = self.position[0], self.position[2]
        omega_ie, omega_en = earth_rate_n(lat), transport_rate_n(V, lat, h)
        r_n_conj = CONJ @ quat_from_rotvec((omega_ie + omega_en) * dt_s)
        r_half_conj = CONJ @ quat_from_rotvec((omega_ie + omega_en) * 0.5 * dt_s)
        step = quat_left(dq_b) @ quat_from_rotvec(-eps * dt_s)                  # Δq_b ⊗ exp(−ε Δt)
        Phi_qq = quat_left(r_n_conj) @ quat_right(step)
        q_new = Phi_qq @ q
        q_mid = quat_left(r_half_conj) @ q
        dv_f = dv_b - nabla * dt_s
        coriolis = 2.0 * omega_ie + omega_en
        g_n = np.array([0.0, 0.0, -normal_gravity(lat, h)])
        V_new = V + rotate(q_mid, dv_f) + (g_n - cross(coriolis, V)) * dt_s
        Phi = np.eye(N_STATES)
        Phi[ATT, ATT] = Phi_qq
        Phi[ATT, GYRO_BIAS] = -0.5 * dt_s * quat_left(q_new) @ VECTOR
        Phi[VEL, ATT] = rotate_jacobian(q_mid, dv_f) @ quat_left(r_half_conj)
        Phi[VEL, VEL] = np.eye(3) - dt_s * skew(coriolis)
        Phi[VEL, ACC_BIAS] = -dt_s * dcm_from_quat(q_mid / np.linalg.norm(q_mid))
        self.x = x.copy()
        self.x[ATT], self.x[VEL] = q_new, V_new
        self.P = Phi @ self.P @ Phi.T + self._process_noise(q_new, dt_s)
        self.P = 0.5 * (self.P + self.P.T)

    def _process_noise(self, q: np.ndarray, dt_s: float) -> np.ndarray:
        """Q of a step: the gyro's angle random walk as ½ q ⊗ [0, δθ], the accelerometer's velocity random walk,
        a slow random walk of each bias."""
        g = self.grade
        Q = np.zeros((N_STATES, N_STATES))
        G = 0.5 * quat_left(q) @ VECTOR
        Q[ATT, ATT] = g.gyro_arw_rad_rts**2 * dt_s * (G @ G.T)
        Q[VEL, VEL] = g.acc_vrw_ms_rts**2 * dt_s * np.eye(3)
        drift = BIAS_INSTABILITY_FRACTION**2 * dt_s / 3600.0
        Q[GYRO_BIAS, GYRO_BIAS] = drift * g.gyro_bias_rad_s**2 * np.eye(3)
        Q[ACC_BIAS, ACC_BIAS] = drift * g.acc_bias_ms2**2 * np.eye(3)
        return Q

    def update(self, q_bm_n: np.ndarray, V_n: np.ndarray, position: np.ndarray) -> None:
        """A master epoch: its quaternion (4,), velocity (3,) m/s and position (3,) (lat rad, lon rad, h m)."""
        s = self.settings
        self.position = np.asarray(position, dtype=float).copy()
        h, H_att, H_mount = master_quaternion(self.q_bs_n, self.q_bs_bm)
        z = np.asarray(q_bm_n, dtype=float) / np.linalg.norm(q_bm_n)
        z = z if z @ h >= 0.0 else -z                            # the quaternion's sign the prediction takes
        H = np.zeros((4, N_STATES))
        H[:, ATT], H[:, MOUNT] = H_att, H_mount
        y = z - h
        R = 0.25 * s.att_std_rad**2 * np.eye(4)                  # the norm direction: a pseudo-measurement of |h|
        if s.velocity_matching:
            H_v = np.zeros((3, N_STATES))
            H_v[:, VEL] = np.eye(3)
            H = np.vstack((H, H_v))
            y = np.concatenate((y, np.asarray(V_n, dtype=float) - self.x[VEL]))
            R = np.block([[R, np.zeros((4, 3))], [np.zeros((3, 4)), s.vel_std_mps**2 * np.eye(3)]])
        S = H @ self.P @ H.T + R
        K = np.linalg.solve(S, H @ self.P).T
        self.x = self.x + K @ y
        I_KH = np.eye(N_STATES) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T
        self._renormalise()

    def _renormalise(self) -> None:
        """Both quaternions back to unit norm, their covariance onto the tangent of the unit sphere."""
        J = np.eye(N_STATES)
        for part in (ATT, MOUNT):
            norm = np.linalg.norm(self.x[part])
            self.x[part] /= norm
            J[part, part] = tangent_projector(self.x[part]) / norm
        self.P = J @ self.P @ J.T
        self.P = 0.5 * (self.P + self.P.T)

    def attitude_sigma(self) -> tuple[float, float]:
        """1-sigma (heading, level) in rad of the slave's attitude, from the covariance of q_bs_n."""
        C = angle_covariance(self.q_bs_n, self.P[ATT, ATT])
        return float(np.sqrt(C[2, 2])), float(np.sqrt(0.5 * (C[0, 0] + C[1, 1])))


@dataclass(frozen=True, slots=True)
class EkfHistory:
    """The filter at the output epochs: t (M,) s, q_bs_n (M, 4), q_bs_bm (M, 4), 1-sigma heading and level (M,)
    rad. Epochs before the first master epoch are NaN."""

    t: np.ndarray
    q_bs_n: np.ndarray
    q_bs_bm: np.ndarray
    heading_sigma_rad: np.ndarray
    level_sigma_rad: np.ndarray


def _sample_index(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Index of the sample (end time) nearest each time; a time more than half a sample from every one is -1."""
    k = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    k = np.where(np.abs(t[k - 1] - times) <= np.abs(t[k] - times), k - 1, k)
    half = 0.5 * (t[1] - t[0]) if len(t) > 1 else np.inf
    return np.where(np.abs(t[k] - times) <= half + 1e-9, k, -1)


def run_transfer_ekf(t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, master: np.ndarray, grade: SensorGrade,
                     settings: EkfSettings, output_t: np.ndarray) -> EkfHistory:
    """Run the filter over a whole recording.

    Parameters
    ----------
    t : (N,) end times of the slave's samples (s); dtheta, dv : (N, 3) its increments (rad, m/s), body axes.
    master : (K, 11) the master's epochs: t, then the pinned columns (:data:`~.transfer.MASTER_COLUMNS`: q of
        C_bm^n [w, x, y, z], vE, vN, vU, lat_deg, lon_deg, h_m), each taken at the sample nearest its time.
    grade : the slave's datasheet. settings : the filter's figures. output_t : (M,) output times (s).
    """
    t = np.asarray(t, dtype=float)
    master = np.asarray(master, dtype=float).reshape(-1, 1 + MASTER_COLUMNS)
    q_b_b0, alpha = InertialIntegrator().integrate(dtheta, dv)
    epoch_index = _sample_index(t, master[:, 0])
    master, epoch_index = master[epoch_index >= 0], epoch_index[epoch_index >= 0]
    _, first = np.unique(epoch_index, return_index=True)         # an epoch sent twice counts once
    master, epoch_index = master[first], epoch_index[first]
    output_index = _sample_index(t, np.asarray(output_t, dtype=float))
    n_out = len(output_index)
    history = EkfHistory(np.asarray(output_t, dtype=float), np.full((n_out, 4), np.nan), np.full((n_out, 4), np.nan),
                         np.full(n_out, np.nan), np.full(n_out, np.nan))
    if len(master) == 0:
        return history
    stride = max(1, round(settings.step_s / (t[1] - t[0]))) if len(t) > 1 else 1
    start = epoch_index[0]
    stops = np.unique(np.concatenate((np.arange(start, len(t), stride), epoch_index, output_index[output_index >= 0])))
    stops = stops[stops >= start]
    epochs = dict(zip(epoch_index.tolist(), master, strict=True))
    outputs: dict[int, list[int]] = {}
    for j, k in enumerate(output_index.tolist()):
        outputs.setdefault(k, []).append(j)

    def position(row: np.ndarray) -> np.ndarray:
        return np.array([np.radians(row[8]), np.radians(row[9]), row[10]])

    ekf = AdditiveQuaternionEkf(grade, settings)
    row = epochs[start]
    ekf.start(row[1:5], row[5:8], position(row))
    previous = start
    for k in stops.tolist():
        if k > previous:
            q_prev = q_b_b0[previous]
            dq_b = quat_left(CONJ @ q_prev) @ q_b_b0[k]
            dv_b = dcm_from_quat(q_prev).T @ (alpha[k] - alpha[previous])
            ekf.predict(dq_b, dv_b, float(t[k] - t[previous]))
            if k in epochs:
                row = epochs[k]
                ekf.update(row[1:5], row[5:8], position(row))
            previous = k
        for j in outputs.get(k, ()):
            history.q_bs_n[j], history.q_bs_bm[j] = ekf.q_bs_n, ekf.q_bs_bm
            history.heading_sigma_rad[j], history.level_sigma_rad[j] = ekf.attitude_sigma()
    return history
