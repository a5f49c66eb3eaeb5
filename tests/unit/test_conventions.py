"""The pinned conventions: ENU / Right-Front-Up, q = [w, x, y, z] of C_b^n, heading clockwise, φ sign."""
import numpy as np
import pytest
from sinsalign.service.align.conventions import (
    DEG,
    dcm_from_euler,
    dcm_from_quat,
    euler_from_dcm,
    misalignment,
    quat_from_dcm,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    rotvec_from_quat,
    skew,
    with_heading_of,
    wrap_pi,
)


def R(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    m = np.eye(3)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def test_euler_order_is_Rz_minus_heading_Rx_pitch_Ry_roll():
    h, p, r = 0.7, -0.2, 0.4
    np.testing.assert_allclose(dcm_from_euler(h, p, r), R(2, -h) @ R(0, p) @ R(1, r), atol=1e-15)


def test_heading_is_clockwise_from_north():
    # body front axis (y) pointing east is heading 90°
    C = dcm_from_euler(90 * DEG, 0.0, 0.0)
    np.testing.assert_allclose(C @ [0, 1, 0], [1, 0, 0], atol=1e-15)
    heading, _pitch, _roll = euler_from_dcm(C)
    assert heading == pytest.approx(90 * DEG)


def test_pitch_nose_up_and_roll_right_wing_down_are_positive():
    np.testing.assert_allclose(dcm_from_euler(0, 10 * DEG, 0) @ [0, 1, 0], [0, np.cos(10 * DEG), np.sin(10 * DEG)])
    # right wing (x) goes down for positive roll
    assert (dcm_from_euler(0, 0, 10 * DEG) @ [1, 0, 0])[2] < 0


@pytest.mark.parametrize("angles", [(0.1, 0.2, -0.3), (5.5, -1.2, 2.9), (3.0, 0.0, 0.0), (0.0, 1.5, -3.0)])
def test_euler_quat_dcm_round_trips(angles):
    C = dcm_from_euler(*angles)
    q = quat_from_dcm(C)
    assert q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(dcm_from_quat(q), C, atol=1e-14)
    h, p, r = euler_from_dcm(C)
    np.testing.assert_allclose(dcm_from_euler(h, p, r), C, atol=1e-14)
    v = np.array([0.3, -1.0, 2.0])
    np.testing.assert_allclose(quat_rotate(q, v), C @ v, atol=1e-14)


def test_quaternion_product_composes_rotations():
    q1, q2 = quat_from_rotvec([0.1, -0.4, 0.9]), quat_from_rotvec([1.2, 0.3, -0.2])
    np.testing.assert_allclose(dcm_from_quat(quat_multiply(q1, q2)), dcm_from_quat(q1) @ dcm_from_quat(q2), atol=1e-14)


def test_rotation_vector_round_trip_small_and_large():
    for phi in ([1e-9, -2e-9, 3e-9], [0.3, 0.2, -0.1], [2.0, -1.0, 0.5]):
        np.testing.assert_allclose(rotvec_from_quat(quat_from_rotvec(phi)), phi, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(dcm_from_quat(quat_from_rotvec([0, 0, 0.5])), R(2, 0.5), atol=1e-15)


def test_skew_is_the_cross_product():
    a, b = np.array([1.0, 2.0, 3.0]), np.array([-0.5, 0.1, 4.0])
    np.testing.assert_allclose(skew(a) @ b, np.cross(a, b))


def test_misalignment_up_component_is_the_clockwise_heading_error():
    C_true = dcm_from_euler(40 * DEG, 3 * DEG, -2 * DEG)
    C_est = dcm_from_euler(40.5 * DEG, 3 * DEG, -2 * DEG)   # estimate 0.5° clockwise of truth
    phi = misalignment(C_est, C_true)
    assert phi[2] == pytest.approx(0.5 * DEG, rel=2e-3)
    # and the definition C_est = (I - [φ×]) C_true holds to first order
    np.testing.assert_allclose(C_est, (np.eye(3) - skew(phi)) @ C_true, atol=1e-4)


def test_wrap_pi():
    np.testing.assert_allclose(wrap_pi(np.array([3 * np.pi, -3 * np.pi + 0.1, 0.2])), [-np.pi, -np.pi + 0.1, 0.2])


@pytest.mark.parametrize("dpsi_deg", [0.01, -0.3, 2.0])
def test_with_heading_of_keeps_one_tilt_and_takes_the_other_heading(dpsi_deg):
    """The tilt (the Up axis seen in the body) of the first, the heading (φ_U = 0) of the second, to rounding."""
    C_level = dcm_from_euler(1.0, 3.0 * DEG, -2.0 * DEG)
    C_heading = dcm_from_euler(1.0 + dpsi_deg * DEG, 3.01 * DEG, -1.98 * DEG)
    C = with_heading_of(C_level, C_heading)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(C.T[:, 2], C_level.T[:, 2], atol=1e-15)
    assert abs(misalignment(C, C_heading)[2]) < 1e-9


def _eigen_quat(C: np.ndarray) -> np.ndarray:
    """The nearest rotation's quaternion from the 4×4 eigenproblem (Bar-Itzhack), w ≥ 0: the reference."""
    K = np.array([[C[0, 0] + C[1, 1] + C[2, 2], C[2, 1] - C[1, 2], C[0, 2] - C[2, 0], C[1, 0] - C[0, 1]],
                  [C[2, 1] - C[1, 2], C[0, 0] - C[1, 1] - C[2, 2], C[1, 0] + C[0, 1], C[0, 2] + C[2, 0]],
                  [C[0, 2] - C[2, 0], C[1, 0] + C[0, 1], -C[0, 0] + C[1, 1] - C[2, 2], C[2, 1] + C[1, 2]],
                  [C[1, 0] - C[0, 1], C[0, 2] + C[2, 0], C[2, 1] + C[1, 2], -C[0, 0] - C[1, 1] + C[2, 2]]])
    q = np.linalg.eigh(K)[1][:, -1]
    return q if q[0] >= 0 else -q


def test_quat_from_dcm_agrees_with_the_eigen_solution_and_gives_one_matrix_the_bits_of_a_stack():
    rng = np.random.default_rng(7)
    q_true = rng.standard_normal((500, 4))
    q_true[:4] = [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0.6, 0.8, 0]]   # 180° turns: w = 0
    q_true = quat_normalize(q_true)
    C = dcm_from_quat(q_true)
    stack = quat_from_dcm(C)
    for k in range(len(C)):
        one = quat_from_dcm(C[k])
        assert one.tobytes() == stack[k].tobytes()
        if q_true[k, 0] > 1e-6:   # a 180° turn's sign is free (q and -q at w = 0): its rotation is checked below
            np.testing.assert_allclose(one, _eigen_quat(C[k]), atol=2e-15)
        np.testing.assert_allclose(dcm_from_quat(one), C[k], atol=2e-15)
    assert np.all(stack[:, 0] >= 0)
    np.testing.assert_allclose(np.abs(np.sum(stack * q_true, axis=-1)), 1.0, atol=1e-15)
