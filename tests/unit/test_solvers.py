"""K-matrix solvers: exact recovery, the OPREQ noise matrix R, and the gain recursions."""
import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_euler, dcm_from_quat, misalignment
from sinsalign.service.align.earth import beta_fixed
from sinsalign.service.align.solvers import RecursiveK, WhitenedWahba, delta_K, request_noise


def random_pairs(n: int, C_b_n: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    r = rng.standard_normal((n, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    return r @ C_b_n, r          # b = C_n^b r


@pytest.mark.parametrize("solver", ["opreq", "request", "qmethod"])
def test_exact_pairs_give_the_attitude_far_from_north(solver):
    C = dcm_from_euler(-130 * DEG, 4 * DEG, -7 * DEG)
    b, r = random_pairs(50, C)
    s = RecursiveK(solver, rho=0.1)
    s.add(b[:20], r[:20], np.full(20, 1e-6))
    s.add(b[20:], r[20:], np.full(30, 1e-6))
    assert np.abs(misalignment(dcm_from_quat(s.quaternion()), C)).max() < 1e-12


def test_noise_matrix_R_matches_the_sample_covariance_of_V():
    """E[V Vᵀ] of V = δK(b + δb, r) - δK(b, r) for δb ~ N(0, μ (I - b bᵀ)): exact (V is linear in δb)."""
    rng = np.random.default_rng(1)
    r = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    b = dcm_from_euler(0.4, 0.2, -0.3).T @ r
    mu = 1e-8
    P = np.eye(3) - np.outer(b, b)
    db = rng.multivariate_normal(np.zeros(3), mu * P, size=200000)
    V = delta_K(b + db, np.broadcast_to(r, db.shape)) - delta_K(b[None], r[None])
    sample = np.einsum("kij,klj->il", V, V) / len(V)
    R = request_noise(b[None], r[None], np.array([mu]))[0]
    np.testing.assert_allclose(sample, R, atol=0.01 * np.abs(R).max())


def test_opreq_gain_is_inverse_variance_weighting():
    """With m = δm = 1, ρ* = P/(P + R) makes K the inverse-trace-R weighted mean of the δK."""
    C = dcm_from_euler(0.3, 0.1, 0.2)
    b, r = random_pairs(6, C, seed=2)
    mu = np.array([4.0, 1.0, 2.0, 0.5, 3.0, 1.5]) * 1e-6
    s = RecursiveK("opreq")
    s.add(b, r, mu)
    trace_R = np.trace(request_noise(b, r, mu), axis1=1, axis2=2)
    w = (1 / trace_R) / (1 / trace_R).sum()
    np.testing.assert_allclose(s.K, np.tensordot(w, delta_K(b, r), axes=1), atol=1e-12)
    assert s.trace_P == pytest.approx(1 / (1 / trace_R).sum())


def test_qmethod_is_the_equally_weighted_mean_and_request_fades():
    b, r = random_pairs(10, np.eye(3), seed=4)
    q = RecursiveK("qmethod")
    q.add(b, r, np.ones(10))
    np.testing.assert_allclose(q.K, delta_K(b, r).mean(axis=0), atol=1e-14)
    assert q.rho == pytest.approx(1 / 10)
    f = RecursiveK("request", rho=0.5)
    f.add(b, r, np.ones(10))
    weights = np.array([0.5 ** (9 - k) * (0.5 if k else 1.0) for k in range(10)])
    np.testing.assert_allclose(f.K, np.tensordot(weights, delta_K(b, r), axes=1), atol=1e-14)


def test_blocks_of_observations_equal_one_at_a_time():
    b, r = random_pairs(12, dcm_from_euler(1.0, 0.1, -0.1), seed=5)
    mu = np.linspace(1e-6, 1e-7, 12)
    whole, single = RecursiveK(), RecursiveK()
    whole.add(b, r, mu)
    for k in range(12):
        single.add(b[k:k + 1], r[k:k + 1], mu[k:k + 1])
    np.testing.assert_allclose(whole.K, single.K, atol=1e-15)
    assert whole.trace_P == pytest.approx(single.trace_P)


def test_bad_solver_settings_are_refused():
    with pytest.raises(ValueError, match="unknown solver"):
        RecursiveK("svd")
    with pytest.raises(ValueError, match="rho"):
        RecursiveK("request", rho=0.0)


def test_centred_wahba_absorbs_a_constant_common_to_all_pairs():
    """The aided-mode trap (docs/algorithms/odometer.md, "Centred solver"): one noisy first sample shifts every
    observation alike."""
    from sinsalign.service.align.conventions import dcm_from_quat, misalignment, quat_from_rotvec
    from sinsalign.service.align.solvers import CentredWahba, RecursiveK
    rng = np.random.default_rng(3)
    q_true = quat_from_rotvec(np.array([0.3, -0.2, 1.1]))
    C_true = dcm_from_quat(q_true)               # C_b^n: r = C b
    r = np.cumsum(rng.normal(size=(200, 3)) + np.array([0.0, 0.0, 5.0]), axis=0)
    b = r @ C_true + np.array([0.05, -0.03, 0.02])   # b = C_n^b r + c (a constant offset)
    centred, plain = CentredWahba(), RecursiveK("qmethod")
    for solver in (centred, plain):
        solver.fold(*solver.prepare(b, r, np.ones(len(b))))
    error = {name: np.degrees(np.abs(misalignment(dcm_from_quat(s.quaternion()), C_true)).max())
             for name, s in (("centred", centred), ("plain", plain))}
    assert error["centred"] < 1e-9 < 1e-3 < error["plain"]
    again = CentredWahba()
    for k in range(0, len(b), 7):   # grouping does not change the bits
        again.fold(*again.prepare(b[k:k + 7], r[k:k + 7], np.ones(7)))
    assert np.array_equal(again.quaternion(), centred.quaternion())


def test_weighted_centred_wahba_screens_a_glitch_pair_and_counts_it():
    """GNSS glitches: a pair far outside the fit's residuals (in units of its stated noise) is left out."""
    from sinsalign.service.align.conventions import dcm_from_quat, misalignment, quat_from_rotvec
    from sinsalign.service.align.solvers import CentredWahba
    rng = np.random.default_rng(5)
    C_true = dcm_from_quat(quat_from_rotvec(np.array([0.1, 0.2, -0.7])))
    r = np.cumsum(rng.normal(size=(300, 3)), axis=0) * 10.0
    b = r @ C_true + 0.1 * rng.normal(size=(300, 3))
    b_glitch = b.copy()
    b_glitch[150:160] += np.array([20.0, 0.0, 0.0])                       # ten pairs 20 m/s off
    mu = np.full(300, 0.1**2)
    screened, unscreened, clean = (CentredWahba(weighted=True, gate_chi2=36.0), CentredWahba(weighted=True),
                                   CentredWahba(weighted=True, gate_chi2=36.0))
    for solver, bb in ((screened, b_glitch), (unscreened, b_glitch), (clean, b)):
        for k in range(300):
            solver.fold(*solver.prepare(bb[k:k + 1], r[k:k + 1], mu[k:k + 1]))
    error = {name: np.degrees(np.abs(misalignment(dcm_from_quat(s.quaternion()), C_true)).max())
             for name, s in (("screened", screened), ("unscreened", unscreened), ("clean", clean))}
    assert screened.rejected == 10 and clean.rejected == 0
    assert max(error["screened"], error["clean"]) < 0.01 < 0.1 < error["unscreened"]
    with pytest.raises(ValueError):
        CentredWahba(gate_chi2=36.0)                                       # screening needs the stated noise


def test_the_screen_reopens_after_a_run_of_rejections_instead_of_locking_the_data_out():
    """A fit gone wrong early (50 pairs of one attitude), then 600 pairs of another 5° away: the screen
    rejects 30 in a row, lets the next 30 through, and the fit follows the data."""
    from sinsalign.service.align.conventions import dcm_from_quat, misalignment, quat_from_rotvec
    from sinsalign.service.align.solvers import GATE_REOPEN_PAIRS, CentredWahba
    rng = np.random.default_rng(7)
    early, late = (dcm_from_quat(quat_from_rotvec(np.array([0.1, 0.2, v]))) for v in (-0.7, -0.7 + np.radians(5)))
    r = np.cumsum(rng.normal(size=(650, 3)), axis=0) * 10.0
    b = np.concatenate((r[:50] @ early, r[50:] @ late)) + 0.1 * rng.normal(size=(650, 3))
    solver = CentredWahba(weighted=True, gate_chi2=36.0)
    for k in range(650):
        solver.fold(*solver.prepare(b[k:k + 1], r[k:k + 1], np.full(1, 0.01)))
    error_deg = np.degrees(np.abs(misalignment(dcm_from_quat(solver.quaternion()), late)).max())
    assert solver.reopened >= 1 and solver.rejected >= GATE_REOPEN_PAIRS
    assert error_deg < 1.0                       # locked out, it would have stayed 5° off


def whitened(arw: float = 2e-6, vrw: float = 3.5e-5, disturbance: float = 1e-3) -> WhitenedWahba:
    return WhitenedWahba(vrw, arw, 9.8, disturbance)


def test_whitened_wahba_recovers_the_attitude_from_exact_cumulative_pairs():
    """GIVEN α = A β exactly on a fixed site, THEN the whitened pairs keep ẽb = A ẽr and the fit is exact."""
    C = dcm_from_euler(-130 * DEG, 4 * DEG, -7 * DEG)           # C_b^n(0): α = C^T β
    t = np.arange(1, 3001) * 0.1
    r = beta_fixed(32 * DEG, 9.8, t)
    s = whitened()
    outer, pairs = s.prepare(r @ C, r, None, t)
    np.testing.assert_allclose(pairs[:, :3], pairs[:, 3:6] @ C, atol=1e-9)
    s.fold(outer, pairs)
    assert np.abs(misalignment(dcm_from_quat(s.quaternion()), C)).max() < 1e-9


def test_the_whitening_filter_turns_the_modelled_noise_into_white_unit_innovations():
    """GIVEN increment noise n_k = g Δt θ_k + (v_k − v_{k−1}) + w_k drawn from the model, THEN the filter's
    innovations divided by √S_k have unit variance and no correlation from one epoch to the next."""
    rng = np.random.default_rng(7)
    arw, vrw, vd, dt, epochs, runs = 2e-5, 3.5e-5, 1e-4, 0.1, 300, 300
    t = np.arange(1, epochs + 1) * dt
    z = np.empty((runs, epochs, 3))
    for j in range(runs):
        theta = np.cumsum(rng.standard_normal((epochs, 3)) * arw * np.sqrt(dt), axis=0)
        v = rng.standard_normal((epochs + 1, 3)) * vd
        noise = 9.8 * dt * theta + np.diff(v, axis=0) + rng.standard_normal((epochs, 3)) * vrw * np.sqrt(dt)
        alpha = np.cumsum(noise, axis=0)                     # cumulative: what the solver is given
        _, pairs = whitened(arw, vrw, vd).prepare(alpha, np.zeros_like(alpha), None, t)
        z[j] = pairs[:, :3] * np.sqrt(pairs[:, 6:7])         # innovation / √S (the weight is 1/S)
    for k in (0, 10, 100, epochs - 1):
        assert np.var(z[:, k]) == pytest.approx(1.0, abs=0.1)
    lag1 = np.mean(z[:, 1:] * z[:, :-1])
    assert abs(lag1) < 0.02
    # the raw increments are far from white: the same statistic on them shows the walk
    raw = np.diff(np.concatenate((np.zeros((1, 3)), alpha)), axis=0)
    assert abs(np.corrcoef(raw[1:, 0], raw[:-1, 0])[0, 1]) > abs(lag1)


def test_whitened_blocks_equal_one_at_a_time():
    C = dcm_from_euler(1.0, 0.1, -0.1)
    t = np.arange(1, 41) * 0.1
    r = beta_fixed(45 * DEG, 9.8, t) + np.random.default_rng(3).standard_normal((40, 3)) * 1e-3
    b = r @ C   # once: a BLAS product's last bits may depend on how many rows it has
    whole, single = whitened(), whitened()
    whole.fold(*whole.prepare(b, r, None, t))
    for k in range(40):
        single.fold(*single.prepare(b[k:k + 1], r[k:k + 1], None, t[k:k + 1]))
    assert np.array_equal(whole.S_br, single.S_br)
    assert np.array_equal(whole.quaternion(), single.quaternion())
