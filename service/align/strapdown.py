"""Strapdown integration in the inertially frozen body frame b0 (alignment-math.md §2).

The integrator keeps O(1) state: the attitude C_{b(t)}^{b0} as a quaternion, the specific-force
integral α(t) = ∫ C_{b(τ)}^{b0} f^b dτ (m/s, b0 axes) and the previous increments for the
single-sample coning and sculling corrections. Samples arrive as increments over
(t_{k-1}, t_k]: Δθ (rad) and Δv (m/s), body axes.

Blocks of samples are integrated at once: the per-sample rotation quaternions are chained with
a parallel prefix product (log2 N vectorised steps), which gives the same attitude as the
sequential product to rounding. One sample is a block of one, so the daemon's per-sample path
and the replay's block path run the same code.
"""
from __future__ import annotations

import numpy as np

from .conventions import quat_from_rotvec, quat_multiply, quat_normalize, quat_rotate


def prefix_quat_product(r: np.ndarray) -> np.ndarray:
    """P_k = r_0 ⊗ r_1 ⊗ … ⊗ r_k for quaternions r of shape (N, 4) (Hillis-Steele scan)."""
    P = np.array(r, dtype=float)
    step = 1
    while step < len(P):
        P[step:] = quat_multiply(P[:-step], P[step:])
        step *= 2
    return P


class InertialIntegrator:
    """Integrates Δθ, Δv into C_{b(t)}^{b0} and α(t), with coning and sculling corrections.

    Coning (single-sample form): φ_k = Δθ_k + (1/12) Δθ_{k-1} × Δθ_k.
    Velocity in b0: C_{b(k-1)}^{b0} [Δv_k + ½ Δθ_k × Δv_k + ⅙ Δθ_k × (Δθ_k × Δv_k)
    + (1/12)(Δθ_{k-1} × Δv_k + Δv_{k-1} × Δθ_k)]. The second-order rotation term makes the
    increment exact to second order both for a specific force fixed in the body and for one fixed
    in inertial space (a swinging base), where the first-order form leaves (1/12)|Δθ|² errors
    that rectify with the swing and show up as heading error.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Restart at b0 = b(now): identity attitude, zero α."""
        self.q_b_b0 = np.array([1.0, 0.0, 0.0, 0.0])
        self.alpha_b0 = np.zeros(3)
        self._dtheta_prev = np.zeros(3)
        self._dv_prev = np.zeros(3)

    def integrate(self, dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integrate a block of samples.

        Parameters
        ----------
        dtheta, dv : (N, 3) gyro angle increments (rad) and velocity increments (m/s), body axes.

        Returns
        -------
        q_b_b0 : (N, 4) attitude C_{b(t_k)}^{b0} at the end of every sample.
        alpha_b0 : (N, 3) α(t_k) in b0 axes (m/s) at the end of every sample.
        """
        dtheta = np.asarray(dtheta, dtype=float).reshape(-1, 3)
        dv = np.asarray(dv, dtype=float).reshape(-1, 3)
        dtheta_prev = np.concatenate((self._dtheta_prev[None], dtheta[:-1]))
        dv_prev = np.concatenate((self._dv_prev[None], dv[:-1]))
        phi = dtheta + np.cross(dtheta_prev, dtheta) / 12.0
        q = quat_multiply(self.q_b_b0, prefix_quat_product(quat_from_rotvec(phi)))
        q = quat_normalize(q)
        q_start = np.concatenate((self.q_b_b0[None], q[:-1]))
        rotated = np.cross(dtheta, dv)
        dv_body = (dv + 0.5 * rotated + np.cross(dtheta, rotated) / 6.0
                   + (np.cross(dtheta_prev, dv) + np.cross(dv_prev, dtheta)) / 12.0)
        alpha = self.alpha_b0 + np.cumsum(quat_rotate(q_start, dv_body), axis=0)
        self.q_b_b0 = q[-1].copy()
        self.alpha_b0 = alpha[-1].copy()
        self._dtheta_prev = dtheta[-1].copy()
        self._dv_prev = dv[-1].copy()
        return q, alpha
