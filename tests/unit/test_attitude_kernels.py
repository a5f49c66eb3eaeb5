"""One attitude's compiled conversions (service/align/_attitude.pyx) against truth and against numpy.

GIVEN Davenport matrices of vector pairs under a known attitude (noiseless, from two well-spread directions to a
cone of 1e-3 rad, as gravity turns with the Earth in the first seconds) and random symmetric matrices, WHEN the
compiled Jacobi eigen-solve gives the quaternion of the top eigenvector, THEN it is unit with w ≥ 0, and within
32 ε max|K| / gap both of the true attitude (a noiseless K) and of numpy.linalg.eigh's eigenvector: the
eigenvector's sensitivity to rounding, ε the double's spacing, gap the difference of K's two largest eigenvalues
(it shrinks with the square of the spread: the heading is ill-determined until gravity has turned). GIVEN random
quaternions, THEN the compiled DCM has dcm_from_quat's bits, and a record's angles, the chained coarse attitude and the
turn to another attitude's heading are within a few units of the last place of the numpy forms they replace (libm's
atan2, asin, sin and cos against numpy's vectorised ones, index-order sums against BLAS's), 180° turns and the poles of
pitch included.
"""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.service.align._attitude import (
    chained_quaternion,
    dcm_from_quat_one,
    fine_record_angles,
    quaternion_from_K,
    record_angles,
    with_heading_of_one,
)
from sinsalign.service.align._compass import platform_attitude
from sinsalign.service.align.conventions import (
    DEG,
    dcm_from_euler,
    dcm_from_quat,
    euler_from_dcm,
    misalignment,
    quat_from_dcm,
    quat_normalize,
    with_heading_of,
)
from sinsalign.service.align.earth import C_n_n0_fixed
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


def random_quaternions(n: int, rng: np.random.Generator) -> np.ndarray:
    """n random unit quaternions, then the hard cases: 180° turns about each axis, level at ±90° pitch."""
    special = [quat_from_dcm(dcm_from_euler(h, p, r)) for h, p, r in
               ((np.pi, 0.0, 0.0), (0.0, 0.0, np.pi), (0.0, np.pi / 2, 0.3), (1.0, -np.pi / 2, 0.0), (0.0, 0.0, 0.0))]
    return np.vstack((quat_normalize(rng.normal(size=(n, 4))), special, [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]))


ULPS = 1e-13   # degrees: a few units of the last place of 360°


def test_a_record_s_angles_are_the_numpy_forms_to_the_last_places():
    rng = np.random.default_rng(7)
    for q in random_quaternions(3000, rng) * (1.0 + 1e-12 * rng.normal(size=(3007, 1))):
        heading, pitch, roll = euler_from_dcm(dcm_from_quat(q))
        q_unit, heading_deg, pitch_deg, roll_deg = record_angles(q)
        want_heading = float(heading / DEG) % 360.0
        assert 0.0 <= heading_deg < 360.0
        assert abs((heading_deg - want_heading + 180.0) % 360.0 - 180.0) < ULPS
        assert (abs(pitch_deg - pitch / DEG) < ULPS and abs(roll_deg - roll / DEG) < ULPS) or abs(pitch_deg) > 89.9
        assert np.abs(np.array(q_unit) - q / np.linalg.norm(q)).max() < 4 * EPS


def test_the_chained_coarse_attitude_and_the_heading_turn_are_the_numpy_forms_to_the_last_places():
    rng = np.random.default_rng(8)
    qs = random_quaternions(2000, rng)
    for a, b in zip(qs, rng.permutation(qs), strict=True):
        C_n_n0 = C_n_n0_fixed(0.6, rng.uniform(0.0, 1e5))
        want = quat_from_dcm(C_n_n0.T @ dcm_from_quat(a) @ dcm_from_quat(b))
        assert np.abs(chained_quaternion(C_n_n0, a, b) - want).max() < 8 * EPS or abs(want[0]) < 1e-6
        C_level, C_heading = dcm_from_quat(a), dcm_from_quat(b)
        turned = with_heading_of_one(C_level, C_heading)
        phi_up = misalignment(C_level, C_heading)[2]
        c, s = np.cos(phi_up), np.sin(phi_up)
        assert np.abs(turned - np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ C_level).max() < 16 * EPS
        assert abs(turned[2] - C_level[2]).max() == 0.0   # a turn about Up: the tilt of the first, as it was


def test_a_fine_record_is_the_output_rule_of_the_coarse_and_the_loops_attitudes():
    rng = np.random.default_rng(9)
    qs = random_quaternions(400, rng)
    omega_ie_n = np.array([0.0, 5e-5, 5e-5])
    for q_b_n0, q_b_b0, q_p in zip(qs, rng.permutation(qs), rng.permutation(qs), strict=True):
        elapsed, since = rng.uniform(0.0, 3600.0), rng.uniform(0.0, 0.1)
        coarse_sigmas, fine_sigmas = rng.uniform(0.01, 1.0, 2), rng.uniform(0.01, 1.0, 2)
        V, rates, gains = rng.normal(0.0, 1e-3, 2), rng.normal(0.0, 1e-5, 3), rng.uniform(-1.0, 3.0, 2)
        on = bool(rng.integers(2))
        C_b0_p = dcm_from_quat(q_p)
        angles = fine_record_angles(0.6, elapsed, q_b_n0, q_b_b0, *coarse_sigmas, *fine_sigmas, C_b0_p, V, *rates, on,
                                    *gains, 1.0, omega_ie_n, 6.4e6, since)
        # the pieces one at a time: coarse.solution_at, CompassLoops.attitude and the output rule
        C_coarse = dcm_from_quat(chained_quaternion(C_n_n0_fixed(0.6, elapsed), q_b_n0, q_b_b0))
        C_fine = platform_attitude(C_b0_p, V, *rates, on, *gains, 1.0, omega_ie_n, 6.4e6, since, dcm_from_quat(q_b_b0))
        level_fine, heading_fine = fine_sigmas[1] < coarse_sigmas[1], fine_sigmas[0] < coarse_sigmas[0]
        C_level = C_fine if level_fine else C_coarse
        want = C_level if level_fine == heading_fine else with_heading_of(C_level, C_fine if heading_fine else C_coarse)
        if not level_fine and not heading_fine:
            want = C_coarse
        q_want = quat_from_dcm(want) if (level_fine or heading_fine) else chained_quaternion(
            C_n_n0_fixed(0.6, elapsed), q_b_n0, q_b_b0)
        assert angles == record_angles(q_want)   # the same bits
