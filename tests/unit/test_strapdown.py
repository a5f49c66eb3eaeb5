"""Simulator exactness and the inertial-frame integrator."""
import copy

import numpy as np
import pytest
from sinsalign.service.align.conventions import (
    DEG,
    cross,
    dcm_from_quat,
    misalignment,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)
from sinsalign.service.align.earth import C_n_n0_fixed, beta_fixed
from sinsalign.service.align.strapdown import InertialIntegrator, prefix_quat_product
from sinsalign.tools.sim.imu import ImuErrors, simulate
from sinsalign.tools.sim.scenarios import get_scenario


def numpy_prefix_product(r: np.ndarray) -> np.ndarray:
    """The Hillis-Steele scan in numpy along the second-last axis, the form the compiled one must match."""
    P = np.array(r, dtype=float)
    step = 1
    while step < P.shape[-2]:
        P[..., step:, :] = quat_multiply(P[..., :-step, :], P[..., step:, :])
        step *= 2
    return P


@pytest.mark.parametrize("shape", [(0, 4), (1, 4), (2, 4), (37, 4), (1200, 4), (5, 20, 4), (3, 0, 4)])
def test_the_compiled_prefix_product_is_the_numpy_scan_to_the_bit(shape):
    r = quat_from_rotvec(0.3 * np.random.default_rng(8).standard_normal((*shape[:-1], 3)))
    got = prefix_quat_product(r)
    assert got.shape == shape and got.tobytes() == numpy_prefix_product(r).tobytes()
    transposed = np.asfortranarray(r)   # any memory order in, the same scan out
    assert prefix_quat_product(transposed).tobytes() == got.tobytes()


def test_prefix_product_equals_sequential_product():
    rng = np.random.default_rng(3)
    r = quat_from_rotvec(0.3 * rng.standard_normal((37, 3)))
    P = prefix_quat_product(r)
    q = np.array([1.0, 0, 0, 0])
    for k in range(len(r)):
        q = quat_multiply(q, r[k])
        np.testing.assert_allclose(P[k], q, atol=1e-14)


def _numpy_integrate(state: list[np.ndarray], dtheta: np.ndarray, dv: np.ndarray, M: int):
    """The block-wise numpy form of the integration (strapdown.md): the oracle of the compiled one. ``state``:
    [q_b_b0, α_b0, Δθ_prev, Δv_prev], updated."""
    q0, alpha0, dtheta_prev0, dv_prev0 = state
    dtheta_prev = np.concatenate((dtheta_prev0[None], dtheta[:-1]))
    dv_prev = np.concatenate((dv_prev0[None], dv[:-1]))
    phi = dtheta + cross(dtheta_prev, dtheta) / 12.0
    local = numpy_prefix_product(quat_from_rotvec(phi).reshape(-1, M, 4))
    rotated = cross(dtheta, dv)
    dv_body = (dv + 0.5 * rotated + cross(dtheta, rotated) / 6.0
               + (cross(dtheta_prev, dv) + cross(dv_prev, dtheta)) / 12.0).reshape(-1, M, 3)
    starts = [q0]
    for total in local[:-1, -1]:
        starts.append(quat_normalize(quat_multiply(starts[-1], total)))
    q_first = np.array(starts)
    q = quat_normalize(quat_multiply(q_first[:, None], local))
    q_start = np.concatenate((q_first[:, None], q[:, :-1]), axis=1)
    within = np.cumsum(quat_rotate(q_start, dv_body), axis=1)
    alpha_first = np.cumsum(np.concatenate((alpha0[None], within[:-1, -1])), axis=0)
    alpha = alpha_first[:, None] + within
    state[:] = q[-1, -1], alpha[-1, -1], dtheta[-1], dv[-1]
    return q.reshape(-1, 4), alpha.reshape(-1, 3)


@pytest.mark.parametrize("M", [1, 2, 7, 20, 200])
def test_the_compiled_integration_is_the_numpy_block_form_to_the_bit(M):
    """The compiled pass must stay the numpy form operation for operation, for any block length, chunks of several
    blocks, rates from still to tumbling (both branches of sin(x)/x) and a long-running state; then a prefix of a block
    integrates alone to the same bits as inside the block (the live path's records of an incomplete block)."""
    rng = np.random.default_rng(M)
    integrator = InertialIntegrator()
    state = [integrator.q_b_b0, integrator.alpha_b0, np.zeros(3), np.zeros(3)]
    for scale in (1e-9, 1e-5, 2e-4, 0.05, 2.0):
        n = 3 * M
        dtheta, dv = scale * rng.standard_normal((n, 3)), 0.05 * rng.standard_normal((n, 3)) + [0, 0, 0.049]
        before = copy.copy(integrator)
        q, alpha = integrator.integrate(dtheta, dv, M)
        q_ref, alpha_ref = _numpy_integrate(state, dtheta, dv, M)
        assert np.array_equal(q, q_ref) and np.array_equal(alpha, alpha_ref)
        assert np.array_equal(integrator.q_b_b0, state[0]) and np.array_equal(integrator.alpha_b0, state[1])
        # the copy taken before runs ahead alone on a block's prefix: the same bits, the original untouched
        ahead = copy.copy(before)
        q_prefix, alpha_prefix = ahead.integrate(dtheta[:max(1, M // 2)], dv[:max(1, M // 2)])
        assert np.array_equal(q_prefix, q[:max(1, M // 2)]) and np.array_equal(alpha_prefix, alpha[:max(1, M // 2)])
        assert not np.array_equal(before.q_b_b0, ahead.q_b_b0) or scale < 1e-8


@pytest.mark.parametrize("layout", ["rows", "reversed", "fortran", "apart"])
def test_the_integration_reads_the_pipeline_s_sample_rows_as_contiguous_arrays(layout):
    """Δθ and Δv as columns of the pipeline's sample rows (t, Δθ, Δv) are read in place; any other layout is
    copied first: the same bits either way."""
    rng = np.random.default_rng(5)
    rows = np.column_stack((np.arange(40.0), 1e-3 * rng.standard_normal((40, 3)), rng.standard_normal((40, 3))))
    if layout == "reversed":
        rows = rows[::-1]
    elif layout == "fortran":
        rows = np.asfortranarray(rows)
    dtheta, dv = rows[:, 1:4], rows[:, 4:7]
    if layout == "apart":   # rows of another stride
        dv = np.ascontiguousarray(dv)
    q, alpha = InertialIntegrator().integrate(dtheta, dv, 20)
    q_ref, alpha_ref = InertialIntegrator().integrate(np.ascontiguousarray(dtheta), np.ascontiguousarray(dv), 20)
    assert np.array_equal(q, q_ref) and np.array_equal(alpha, alpha_ref)


def test_a_chunk_that_is_not_whole_blocks_is_refused():
    with pytest.raises(ValueError, match="not whole blocks of 20"):
        InertialIntegrator().integrate(np.zeros((30, 3)), np.zeros((30, 3)), 20)


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
