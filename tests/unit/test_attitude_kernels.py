"""One attitude's compiled conversions (service/align/_attitude.pyx) against truth and against numpy.

GIVEN Davenport matrices of vector pairs under a known attitude (noiseless, from two well-spread directions to a
cone of 1e-3 rad, as gravity turns with the Earth in the first seconds) and random symmetric matrices, WHEN the
compiled Jacobi eigen-solve gives the quaternion of the top eigenvector, THEN it is unit with w ≥ 0, and within
32 ε max|K| / gap both of the true attitude (a noiseless K) and of numpy.linalg.eigh's eigenvector: the
eigenvector's sensitivity to rounding, ε the double's spacing, gap the difference of K's two largest eigenvalues
(it shrinks with the square of the spread: the heading is ill-determined until gravity has turned). GIVEN random
quaternions, THEN the compiled DCM has dcm_from_quat's bits.
"""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.service.align._attitude import dcm_from_quat_one, quaternion_from_K
from sinsalign.service.align.conventions import dcm_from_quat, quat_from_dcm, quat_normalize
from sinsalign.service.align.solvers import delta_K

EPS = np.finfo(float).eps
BOUND = 32.0   # × ε max|K| / gap (module docstring)


def eigh_quaternion(K: np.ndarray) -> tuple[np.ndarray, float]:
    """numpy's top eigenvector of K as a quaternion (w ≥ 0), and the gap of K's two largest eigenvalues."""
    values, vectors = np.linalg.eigh(K)
    top = vectors[:, -1]
    return quat_normalize(np.array([top[3], top[0], top[1], top[2]])), values[-1] - values[-2]


def pairs_K(C_b_n: np.ndarray, spread_rad: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """K of n unit reference vectors within ``spread_rad`` of a random axis (r, navigation axes) and their body
    images b = C_n^b r."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    r = axis + spread_rad * rng.normal(size=(n, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    return delta_K(r @ C_b_n, r).sum(axis=0)


@pytest.mark.parametrize("spread_rad", [1.0, 1e-1, 1e-2, 1e-3])
def test_a_noiseless_K_gives_its_attitude_and_eighs_eigenvector(spread_rad):
    rng = np.random.default_rng(int(1 / spread_rad))
    for _ in range(200):
        q_true = quat_normalize(rng.normal(size=4))
        K = pairs_K(dcm_from_quat(q_true), spread_rad, 20, rng)
        q = quaternion_from_K(K)
        assert q[0] >= 0.0 and abs(np.linalg.norm(q) - 1.0) <= 4 * EPS
        q_eigh, gap = eigh_quaternion(K)
        assert np.max(np.abs(q - q_eigh)) <= BOUND * EPS * np.max(np.abs(K)) / gap
        # the true attitude, within what the rounding of K itself allows at this spread
        error = dcm_from_quat(q) @ dcm_from_quat(q_true).T
        assert np.max(np.abs(error - error.T)) / 2.0 <= BOUND * EPS * np.max(np.abs(K)) / gap


def test_any_symmetric_K_gives_eighs_top_eigenvector():
    rng = np.random.default_rng(4)
    for _ in range(2000):
        A = rng.normal(size=(4, 4)) * 10.0 ** rng.uniform(-6, 6)
        K = A + A.T
        q_eigh, gap = eigh_quaternion(K)
        assert np.max(np.abs(quaternion_from_K(K) - q_eigh)) <= BOUND * EPS * np.max(np.abs(K)) / gap


def test_the_compiled_dcm_has_numpys_bits():
    rng = np.random.default_rng(5)
    q = quat_normalize(rng.normal(size=(1000, 4)))
    stacked = dcm_from_quat(q)
    for k in range(len(q)):
        assert dcm_from_quat_one(q[k]).tobytes() == stacked[k].tobytes()
        assert quat_from_dcm(dcm_from_quat_one(q[k])).tobytes() == quat_from_dcm(stacked[k]).tobytes()
