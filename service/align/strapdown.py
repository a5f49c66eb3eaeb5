"""Strapdown integration in the inertially frozen body frame b0 (docs/algorithms/strapdown.md).

The integrator keeps O(1) state: the attitude C_{b(t)}^{b0} as a quaternion, the specific-force
integral α(t) = ∫ C_{b(τ)}^{b0} f^b dτ (m/s, b0 axes) and the previous increments for the
single-sample coning and sculling corrections. Samples arrive as increments over
(t_{k-1}, t_k]: Δθ (rad) and Δv (m/s), body axes.

Blocks of samples are integrated at once: the per-sample rotation quaternions are chained with
a parallel prefix product (log2 N vectorised steps), which gives the same attitude as the
sequential product to rounding. With ``block_samples`` = M the chunk is cut into blocks of M
samples, each scanned on its own and chained to the previous one: the arithmetic of a block then
depends on its M samples only, so a stream fed one block at a time and a file fed in large
chunks give bit-identical results.
"""
from __future__ import annotations

import math

import numpy as np

from .conventions import cross, quat_from_rotvec, quat_multiply, quat_normalize, quat_rotate


def prefix_quat_product(r: np.ndarray) -> np.ndarray:
    """P_k = r_0 ⊗ r_1 ⊗ … ⊗ r_k along the second-last axis of r (..., N, 4) (Hillis-Steele scan)."""
    P = np.array(r, dtype=float)
    n = P.shape[-2]
    step = 1
    while step < n:
        P[..., step:, :] = quat_multiply(P[..., :-step, :], P[..., step:, :])
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

    def integrate(self, dtheta: np.ndarray, dv: np.ndarray,
                  block_samples: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Integrate a chunk of samples.

        Parameters
        ----------
        dtheta, dv : (N, 3) gyro angle increments (rad) and velocity increments (m/s), body axes.
        block_samples : cut the chunk into blocks of this many samples (N must be a multiple);
            None: one block.

        Returns
        -------
        q_b_b0 : (N, 4) attitude C_{b(t_k)}^{b0} at the end of every sample.
        alpha_b0 : (N, 3) α(t_k) in b0 axes (m/s) at the end of every sample.
        """
        dtheta = np.asarray(dtheta, dtype=float).reshape(-1, 3)
        dv = np.asarray(dv, dtype=float).reshape(-1, 3)
        n = len(dtheta)
        M = block_samples or n
        if n % M:
            raise ValueError(f"{n} samples are not whole blocks of {M}")
        dtheta_prev = np.concatenate((self._dtheta_prev[None], dtheta[:-1]))
        dv_prev = np.concatenate((self._dv_prev[None], dv[:-1]))
        phi = dtheta + cross(dtheta_prev, dtheta) / 12.0
        local = prefix_quat_product(quat_from_rotvec(phi).reshape(-1, M, 4))
        rotated = cross(dtheta, dv)
        dv_body = (dv + 0.5 * rotated + cross(dtheta, rotated) / 6.0
                   + (cross(dtheta_prev, dv) + cross(dv_prev, dtheta)) / 12.0).reshape(-1, M, 3)
        # each block starts from the attitude the previous one ended with: only that chain is sequential, and it
        # runs on the blocks' last samples alone; the rest is the same elementwise arithmetic over all blocks
        q_first = _chain_block_starts(self.q_b_b0, local[:, -1])
        q = quat_normalize(quat_multiply(q_first[:, None], local))
        q_start = np.concatenate((q_first[:, None], q[:, :-1]), axis=1)
        within = np.cumsum(quat_rotate(q_start, dv_body), axis=1)
        alpha_first = np.cumsum(np.concatenate((self.alpha_b0[None], within[:-1, -1])), axis=0)
        alpha = alpha_first[:, None] + within
        self.q_b_b0, self.alpha_b0 = q[-1, -1].copy(), alpha[-1, -1].copy()
        self._dtheta_prev = dtheta[-1].copy()
        self._dv_prev = dv[-1].copy()
        return q.reshape(-1, 4), alpha.reshape(-1, 3)


def _chain_block_starts(q_start: np.ndarray, block_totals: np.ndarray) -> np.ndarray:
    """The attitude (K, 4) each of K blocks starts from: ``q_start``, then normalize(previous ⊗ total) block by
    block, ``block_totals`` (K, 4) being each block's own product of its samples' rotations.

    Plain floats, one block at a time, the same operations in the same order as :func:`quat_multiply` and
    :func:`quat_normalize` apply elementwise: the same bits as chaining whole blocks with them, without numpy's
    per-call cost on 4 numbers.
    """
    starts = np.empty((len(block_totals), 4))
    pw, px, py, pz = (float(c) for c in q_start)
    for k, (qw, qx, qy, qz) in enumerate(block_totals.tolist()):
        starts[k] = pw, px, py, pz
        w = pw * qw - px * qx - py * qy - pz * qz
        x = pw * qx + px * qw + py * qz - pz * qy
        y = pw * qy - px * qz + py * qw + pz * qx
        z = pw * qz + px * qy - py * qx + pz * qw
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        pw, px, py, pz = w / norm, x / norm, y / norm, z / norm
        if pw < 0.0:
            pw, px, py, pz = -pw, -px, -py, -pz
    return starts
