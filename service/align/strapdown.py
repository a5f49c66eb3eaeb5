"""Strapdown integration in the inertially frozen body frame b0 (docs/algorithms/strapdown.md).

The integrator keeps O(1) state: the attitude C_{b(t)}^{b0} as a quaternion, the specific-force
integral α(t) = ∫ C_{b(τ)}^{b0} f^b dτ (m/s, b0 axes) and the previous increments for the
single-sample coning and sculling corrections. Samples arrive as increments over
(t_{k-1}, t_k]: Δθ (rad) and Δv (m/s), body axes.

Blocks of samples are integrated at once: the per-sample rotation quaternions are chained with
a parallel prefix product (Hillis-Steele, log2 M steps a block), which gives the same attitude as
the sequential product to rounding. The pass is compiled (_strapdown.pyx, the numpy block form's
operations in its order: the same bits). With ``block_samples`` = M the chunk is cut into blocks of M
samples, each scanned on its own and chained to the previous one: the arithmetic of a block then
depends on its M samples only, so a stream fed one block at a time and a file fed in large
chunks give bit-identical results.
"""
from __future__ import annotations

import numpy as np

from ._strapdown import integrate as integrate_blocks
from ._strapdown import prefix_product


def prefix_quat_product(r: np.ndarray) -> np.ndarray:
    """P_k = r_0 ⊗ r_1 ⊗ … ⊗ r_k along the second-last axis of r (..., N, 4) (Hillis-Steele scan, compiled:
    _strapdown.prefix_product)."""
    P = np.array(r, dtype=float, order="C")
    if P.size:
        prefix_product(P.reshape(-1, *P.shape[-2:]))   # a view of the fresh copy: scanned in place
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
        state, q, alpha = self._run(dtheta, dv, block_samples)
        self.q_b_b0, self.alpha_b0, self._dtheta_prev, self._dv_prev = state
        return q, alpha

    def ahead(self, dtheta: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """C_{b(t_k)}^{b0} (N, 4) at the ends of N samples after the integrated ones, as one block, the state left as
        it is: the same bits as integrating them (a block's first samples alone are as within the whole block)."""
        return self._run(dtheta, dv, None)[1]

    def _run(self, dtheta: np.ndarray, dv: np.ndarray, block_samples: int | None
             ) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray]:
        """(the state after the samples, C_b^b0 (N, 4), α (N, 3)), the state's own arrays untouched: new ones are
        written, so a shallow copy of the integrator (the pipeline's scratch) runs ahead on its own."""
        dtheta, dv = _rows(dtheta, dv)
        state = (self.q_b_b0.copy(), self.alpha_b0.copy(), self._dtheta_prev.copy(), self._dv_prev.copy())
        q, alpha = integrate_blocks(*state, dtheta, dv, block_samples or len(dtheta))
        return state, q, alpha


def _rows(dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Δθ and Δv (N, 3) as the compiled integration reads them: as they are when each row is contiguous and both step
    by one stride (the pipeline's sample rows: no copy), else contiguous copies."""
    dtheta, dv = np.reshape(np.asarray(dtheta, dtype=float), (-1, 3)), np.reshape(np.asarray(dv, dtype=float), (-1, 3))
    if (dtheta.strides[1] == dv.strides[1] == dtheta.itemsize and dtheta.strides[0] == dv.strides[0]
            and dtheta.strides[0] % dtheta.itemsize == 0):
        return dtheta, dv
    return np.ascontiguousarray(dtheta), np.ascontiguousarray(dv)
