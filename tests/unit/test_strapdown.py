"""Simulator exactness and the inertial-frame integrator."""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment, quat_from_rotvec, quat_multiply
from sinsalign.service.align.earth import C_n_n0_fixed, beta_fixed
from sinsalign.service.align.strapdown import InertialIntegrator, prefix_quat_product
from sinsalign.tools.sim.imu import ImuErrors, simulate
from sinsalign.tools.sim.scenarios import get_scenario


def test_prefix_product_equals_sequential_product():
    rng = np.random.default_rng(3)
    r = quat_from_rotvec(0.3 * rng.standard_normal((37, 3)))
    P = prefix_quat_product(r)
    q = np.array([1.0, 0, 0, 0])
    for k in range(len(r)):
        q = quat_multiply(q, r[k])
        np.testing.assert_allclose(P[k], q, atol=1e-14)


def test_the_plain_float_block_chain_is_quat_multiply_then_quat_normalize_to_the_bit():
    """The chain of block starts repeats quat_multiply and quat_normalize in plain floats (numpy's per-call cost on
    4 numbers); it must stay their exact copy, or a replay and the live path would part at the block boundaries."""
    from sinsalign.service.align.conventions import quat_normalize
    from sinsalign.service.align.strapdown import _chain_block_starts
    rng = np.random.default_rng(7)
    totals = quat_from_rotvec(0.3 * rng.standard_normal((200, 3)))
    start = quat_normalize(rng.standard_normal(4))
    chained = _chain_block_starts(start, totals)
    expected = [start]
    for total in totals[:-1]:
        expected.append(quat_normalize(quat_multiply(expected[-1], total)))
    assert np.array_equal(chained, np.array(expected))


def test_perfect_strapdown_recovers_the_simulated_truth_over_600_s():
    """Exact increments: body integrator + Earth rotation reproduce C_b^n(t) to < 1e-6° for 600 s of swing."""
    scenario = get_scenario("seed000-swing")
    C0 = scenario.motion.attitude(np.array(0.0))
    integrator = InertialIntegrator()
    worst = 0.0
    for chunk in simulate(scenario.motion, scenario.site, ImuErrors(), 200.0, 600.0, seed=0, chunk_samples=4000):
        q, _ = integrator.integrate(chunk.dtheta, chunk.dv)
        C = np.swapaxes(C_n_n0_fixed(scenario.site.lat, chunk.t), -1, -2) @ C0 @ dcm_from_quat(q)
        worst = max(worst, float(np.abs(misalignment(C, chunk.C_b_n_true)).max()))
    assert worst / DEG < 1e-6


def test_specific_force_integral_matches_the_closed_form_on_a_swinging_base():
    """α(t) = C_n^b(0) β(t) exactly when the base does not translate; 2nd-order rotation term included."""
    scenario = get_scenario("seed000-swing")
    C0 = scenario.motion.attitude(np.array(0.0))
    integrator = InertialIntegrator()
    worst = 0.0
    for chunk in simulate(scenario.motion, scenario.site, ImuErrors(), 200.0, 100.0, seed=0):
        _, alpha = integrator.integrate(chunk.dtheta, chunk.dv)
        expected = beta_fixed(scenario.site.lat, scenario.site.gravity, chunk.t) @ C0
        worst = max(worst, float(np.abs(alpha - expected).max()))
    assert worst < 1e-6   # m/s, after 100 s (|α| ≈ 980 m/s)


def test_block_and_sample_by_sample_integration_agree():
    scenario = get_scenario("seed000-swing")
    chunk = next(simulate(scenario.motion, scenario.site, scenario.errors, 200.0, 5.0, seed=2))
    block, single = InertialIntegrator(), InertialIntegrator()
    q_block, a_block = block.integrate(chunk.dtheta, chunk.dv)
    for k in range(len(chunk.t)):
        q_one, a_one = single.integrate(chunk.dtheta[k], chunk.dv[k])
    np.testing.assert_allclose(q_one[-1], q_block[-1], atol=1e-13)
    np.testing.assert_allclose(a_one[-1], a_block[-1], rtol=0, atol=1e-12 * np.linalg.norm(a_block[-1]))


def test_quaternion_stays_unit_over_a_long_stream():
    integrator = InertialIntegrator()
    rng = np.random.default_rng(0)
    for _ in range(50):
        q, _ = integrator.integrate(0.05 * rng.standard_normal((2000, 3)), rng.standard_normal((2000, 3)))
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-14


def test_simulated_noise_has_the_requested_size():
    scenario = get_scenario("static")
    dt = 1 / 200.0
    errors = ImuErrors(gyro_noise_rad_s=1e-3, acc_vrw_ms_rts=1e-3)
    chunks = list(simulate(scenario.motion, scenario.site, errors, 200.0, 100.0, seed=5))
    ideal = list(simulate(scenario.motion, scenario.site, ImuErrors(), 200.0, 100.0, seed=5))
    dth = np.concatenate([c.dtheta - i.dtheta for c, i in zip(chunks, ideal, strict=True)])
    dv = np.concatenate([c.dv - i.dv for c, i in zip(chunks, ideal, strict=True)])
    assert dth.std() == pytest.approx(1e-3 * dt, rel=0.02)
    assert dv.std() == pytest.approx(1e-3 * np.sqrt(dt), rel=0.02)
