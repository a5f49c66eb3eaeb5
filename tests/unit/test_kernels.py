"""The compiled kernels against the numpy arithmetic they replace (service/align/_kernels.pyx).

GIVEN random sites, times and vectors, WHEN a kernel and the numpy expression it stands for evaluate them, THEN the
closed forms agree to the bit and the sums of products to a few units of the last place; the noise meter's loop
gives the same sums, counts and events as the per-observation numpy stencil, and the same bits however a stream is
split into calls. GIVEN the meter's fits at 3 to 5 lags (densities some of them zero, χ² scatter), THEN the compiled
non-negative fit takes numpy's active set, its figures and standard errors to 1e-9 relative (QR and Jacobi against
numpy's SVD, on designs whose column-scaled condition is about 1e3), and a signal without noise fits to zero.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from sinsalign.service.align._kernels import (
    C_n_n0_fixed_at,
    beta_fixed_at,
    beta_fixed_many,
    horizontal_gained,
    noise_figures,
    recursive_k_prepare,
    store_and_gain,
    weighted_nonnegative_fit,
)
from sinsalign.service.align.conventions import dcm_from_euler
from sinsalign.service.align.earth import C_n_n0_fixed, Site, beta_fixed
from sinsalign.service.align.noise_check import (
    LAGS_S,
    MIN_MEAN_SQUARE,
    MIN_OUTLIER_COUNT,
    MIN_SPAN_S,
    OUTLIER_FACTOR,
    SETTLE_S,
    STENCIL,
    NoiseMeter,
)
from sinsalign.service.align.solvers import RecursiveK, delta_K, request_noise

RNG = np.random.default_rng(27)
# both branches of t − sin(Ωt)/Ω (its series below Ωt = 1e-3, about 14 s) and a day
TIMES_S = np.concatenate((RNG.uniform(0.0, 14.0, 400), RNG.uniform(14.0, 86400.0, 400)))
LATS = RNG.uniform(-1.55, 1.55, len(TIMES_S))


def test_the_fixed_site_closed_forms_have_numpys_bits():
    for t, lat in zip(TIMES_S, LATS, strict=True):
        assert beta_fixed_at(lat, 9.79, t).tobytes() == beta_fixed(lat, 9.79, t).tobytes()
        assert C_n_n0_fixed_at(lat, t).tobytes() == C_n_n0_fixed(lat, t).tobytes()
    assert beta_fixed_many(0.6, 9.79, TIMES_S).tobytes() == beta_fixed(0.6, 9.79, TIMES_S).tobytes()


@pytest.mark.parametrize("M", [1, 2, 3, 500])
def test_the_k_matrix_pairs_are_the_numpy_forms_to_the_bit(M):
    """RecursiveK.prepare compiled: the normalised pairs' δK and tr R with numpy's bits (its einsum adds three squares
    in its own order), for any number of pairs and vectors far from unit length."""
    b = RNG.standard_normal((M, 3)) * RNG.uniform(1e-3, 1e3, (M, 1))
    r = RNG.standard_normal((M, 3)) * RNG.uniform(1e-3, 1e3, (M, 1))
    mu = RNG.uniform(1e-12, 1e-4, M)
    dK, trace_R = recursive_k_prepare(b, r, mu)
    b_unit = b / np.sqrt(np.einsum("mi,mi->m", b, b))[:, None]
    r_unit = r / np.sqrt(np.einsum("mi,mi->m", r, r))[:, None]
    assert dK.tobytes() == delta_K(b_unit, r_unit).tobytes()
    assert trace_R.tobytes() == np.trace(request_noise(b_unit, r_unit, mu), axis1=1, axis2=2).tobytes()


def numpy_fold(solver: RecursiveK, dK: np.ndarray, trace_R: np.ndarray) -> tuple:
    """RecursiveK's fold in Python and numpy, the form the compiled fold must match: (K, m, tr P, n, ρ)."""
    m, trace_P, n, K, rho = solver.m, solver.trace_P, solver.n_obs, solver.K, solver.rho
    for j, tr_R in enumerate(trace_R):
        if n == 0:
            K, m, trace_P, rho = dK[j].copy(), 1.0, float(tr_R), 1.0
        else:
            trace_P += solver.trace_Q
            rho = (m * m * trace_P / (m * m * trace_P + tr_R) if solver.solver == "opreq" else solver.fixed_rho
                   if solver.solver == "request" else 1.0 / (n + 1.0))
            m_new = (1.0 - rho) * m + rho
            a, c = (1.0 - rho) * m / m_new, rho / m_new
            trace_P = a * a * trace_P + c * c * tr_R
            K = a * K + c * dK[j]
            m = m_new
        n += 1
    return K, m, trace_P, n, rho


@pytest.mark.parametrize("name", ["opreq", "request", "qmethod"])
def test_the_k_matrix_fold_is_the_numpy_fold_to_the_bit(name):
    """RecursiveK.fold compiled: K, m, tr P, n and ρ with the Python fold's bits, in groups of any size (the first
    observation starting K), with process noise; the K it replaces is left as it was (a scratch copy shares it)."""
    dK, trace_R = recursive_k_prepare(RNG.standard_normal((300, 3)), RNG.standard_normal((300, 3)),
                                      RNG.uniform(1e-12, 1e-4, 300))
    solver = RecursiveK(name, rho=0.05, trace_Q=1e-9)
    start = 0
    for size in (1, 2, 7, 90, 200):
        expected = numpy_fold(solver, dK[start:start + size], trace_R[start:start + size])
        before = solver.K
        kept = before.copy()
        solver.fold(dK[start:start + size], trace_R[start:start + size])
        got = (solver.K, solver.m, solver.trace_P, solver.n_obs, solver.rho)
        assert got[0].tobytes() == expected[0].tobytes() and got[1:] == expected[1:]
        assert np.array_equal(before, kept)
        start += size
    assert solver.n_obs == 300


def test_the_velocity_gained_is_numpys_to_the_last_bits():
    for t, lat in zip(TIMES_S[::8], LATS[::8], strict=True):
        C_b0_n0 = dcm_from_euler(*RNG.uniform(-np.pi, np.pi, 3))
        alpha, alpha_from, beta_from = RNG.normal(0.0, 100.0, (3, 3))
        beta = beta_fixed(lat, 9.79, t)
        C_n0_n = C_n_n0_fixed(lat, t).T
        gained = C_n0_n @ (C_b0_n0 @ (alpha - alpha_from) - (beta - beta_from))
        turn = C_n0_n @ (beta - beta_from)
        expected = (np.hypot(gained[0], gained[1]), np.hypot(turn[0], turn[1]))
        # the transposed view as the monitor passes it: strided input is read as it is
        got = horizontal_gained(lat, t, C_b0_n0.T.T, alpha, beta, alpha_from, beta_from)
        np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13 * np.abs(alpha).max())


def test_the_motion_ring_entry_and_speed_are_the_separate_kernels_to_the_bit():
    """store_and_gain: the entry holds the time, α, β of the fixed site there and C_b0^n0 as given, and the speed
    gained since another entry is horizontal_gained's over those (the same bits); without ``gain``, NaN."""
    n = 5
    ring = np.full(n, np.nan), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3))
    for k, (t, lat) in enumerate(zip(TIMES_S[:40], LATS[:40], strict=True)):
        alpha = RNG.normal(0.0, 100.0, 3)
        C_b0_n0 = dcm_from_euler(*RNG.uniform(-np.pi, np.pi, 3))
        slot, oldest = k % n, (k + 1) % n
        speed = store_and_gain(lat, 9.79, t, alpha, C_b0_n0, *ring, slot, oldest, k >= n - 1)
        assert ring[0][slot] == t and ring[1][slot].tobytes() == alpha.tobytes()
        assert ring[2][slot].tobytes() == beta_fixed_at(lat, 9.79, t).tobytes()
        assert ring[3][slot].tobytes() == C_b0_n0.tobytes()
        if k < n - 1:
            assert np.isnan(speed)
        else:
            expected, _ = horizontal_gained(lat, t, ring[3][oldest], alpha, ring[2][slot], ring[1][oldest],
                                            ring[2][oldest])
            assert speed == expected


def reference_meter(meter: NoiseMeter, elapsed_s: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, ...]:
    """The meter's loop written per observation in numpy: (sums, counts, outliers, moments)."""
    lags = meter._lags
    capacity = 4 * int(lags.max()) + 1
    offsets = np.arange(5)[None, :] * lags[:, None]
    alpha_sum, beta_sum, last = np.zeros((capacity, 3)), np.zeros((capacity, 3)), np.zeros((2, 3))
    sums, counts, outliers, bad_until = np.zeros(len(lags)), np.zeros(len(lags)), 0, -1
    trend = np.zeros((3, 2, 3))   # Σ tᵏ α, Σ tᵏ β for k = 0..2
    for k, (t, a) in enumerate(zip(elapsed_s, alpha, strict=True)):
        pair = np.stack((a, beta_fixed(meter._lat, meter._gravity, t)))
        last += pair
        trend += np.array([1.0, t, t * t])[:, None, None] * pair
        alpha_sum[k % capacity], beta_sum[k % capacity] = last
        ready = k >= 4 * lags
        if not ready[0]:
            continue
        index = (k - offsets) % capacity
        d = STENCIL @ alpha_sum[index]
        if meter.C_n0_b0 is not None:
            d = d - (STENCIL @ beta_sum[index]) @ meter.C_n0_b0.T
        d = d / lags[:, None]
        up = a / np.linalg.norm(a)
        squares = 0.5 * (np.einsum("ij,ij->i", d, d) - (d @ up) ** 2)
        if counts[0] >= MIN_OUTLIER_COUNT and squares[0] > OUTLIER_FACTOR * sums[0] / counts[0]:
            outliers += 1
            bad_until = k + round(SETTLE_S / meter.step_s)
        clean = ready & (k - 4 * lags > bad_until)
        sums[clean] += squares[clean]
        counts[clean] += 1
    moments = np.concatenate((trend.ravel(), [np.sum(elapsed_s**k) for k in range(5)]))
    return sums, counts, outliers, moments


def meter_stream(seconds: float, step_s: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """α of a fixed base with white noise and two knocks (jumps of α, whose stencils the meter must leave out)."""
    site = Site(0.6)
    t = np.arange(1, round(seconds / step_s) + 1) * step_s
    C_n0_b0 = dcm_from_euler(0.01, -0.02, 1.1)
    alpha = beta_fixed(site.lat, site.gravity, t) @ C_n0_b0.T + np.cumsum(RNG.normal(0.0, 1e-4, (len(t), 3)), axis=0)
    for at in (0.4, 0.7):
        alpha[round(at * len(t)):] += (0.05, -0.03, 0.0)
    return t, alpha


@pytest.mark.parametrize("with_estimate", [False, True])
def test_the_noise_meters_loop_is_the_numpy_stencil(with_estimate):
    t, alpha = meter_stream(200.0)
    meter = NoiseMeter(0.1, 0.6, Site(0.6).gravity)
    if with_estimate:
        meter.C_n0_b0 = dcm_from_euler(0.01, -0.02, 1.1) @ dcm_from_euler(0.0, 0.0, 0.03)
    sums, counts, outliers, moments = reference_meter(meter, t, alpha)
    meter.feed(t, alpha)
    assert meter.outliers == outliers >= 2   # each knock's stencils stand out
    assert meter._counts.tolist() == counts.tolist()
    np.testing.assert_allclose(meter._moments, moments, rtol=1e-12)
    # each stencil takes differences of running sums some 1e6 times its result: the order of its five terms (numpy's
    # BLAS against the loop) moves the last 1e-9 of it, as any other order would
    np.testing.assert_allclose(meter._sums, sums, rtol=1e-7)


def test_the_noise_meter_gives_the_same_bits_however_the_stream_is_split():
    t, alpha = meter_stream(120.0)
    whole = NoiseMeter(0.1, 0.6, Site(0.6).gravity)
    assert whole.feed(t, alpha)
    split = NoiseMeter(0.1, 0.6, Site(0.6).gravity)
    cuts = np.unique(RNG.integers(0, len(t), 40))
    due = [split.feed(t[a:b], alpha[a:b]) for a, b in zip((0, *cuts), (*cuts, len(t)), strict=True)]
    assert split._sums.tobytes() == whole._sums.tobytes() and split._counts.tobytes() == whole._counts.tobytes()
    assert split._moments.tobytes() == whole._moments.tobytes()
    assert (split.steps, split.outliers) == (whole.steps, whole.outliers)
    # a verdict is due in every call that crossed a multiple of ten observations
    ends = np.array([*cuts, len(t)])
    starts = np.array([0, *cuts])
    assert due == [bool(b // 10 > a // 10) for a, b in zip(starts, ends, strict=True)]


def numpy_nonnegative_fit(A: np.ndarray, m: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The noise meter's fit in numpy: x ≥ 0 minimising Σ w (A x − m)² over the 7 active sets by lstsq, and the
    unconstrained fit's standard errors from the pseudo-inverse of the column-scaled normal matrix."""
    Aw, mw = A * np.sqrt(weights)[:, None], m * np.sqrt(weights)
    normal = Aw.T @ Aw
    scale = np.sqrt(np.diag(normal))
    covariance = np.linalg.pinv(normal / np.outer(scale, scale)) / np.outer(scale, scale)
    best, best_cost = np.zeros(3), float(mw @ mw)
    for size in range(1, 4):
        for cols in itertools.combinations(range(3), size):
            x_sub = np.linalg.lstsq(Aw[:, list(cols)], mw, rcond=None)[0]
            if (x_sub < 0.0).any():
                continue
            x = np.zeros(3)
            x[list(cols)] = x_sub
            cost = float(np.sum((Aw @ x - mw) ** 2))
            if cost < best_cost:
                best, best_cost = x, cost
    return best, np.sqrt(np.maximum(np.diag(covariance), 0.0))


def meter_problem(rng: np.random.Generator, lags: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The meter's fit at ``lags`` lags (1 s, 2 s …): its design, mean squares of random densities (some zero, so the
    constraint binds) with χ² scatter, and their weights."""
    lag_s = 2.0 ** np.arange(lags)
    A = np.column_stack((8.0 / 3.0 * lag_s, 2.0 / 3.0 * 9.8**2 * lag_s**3, 20.0 / lag_s))
    truth = 10.0 ** rng.uniform(-14, -8, 3) * (rng.uniform(size=3) > 0.3)
    m = A @ truth * rng.chisquare(20, lags) / 20 + 1e-20
    return A, m, 50.0 / (2.0 * m**2)


@pytest.mark.parametrize("lags", [3, 4, 5])
def test_the_nonnegative_fit_is_numpys(lags):
    rng = np.random.default_rng(lags)
    for _ in range(300):
        A, m, w = meter_problem(rng, lags)
        x, se = weighted_nonnegative_fit(A, m, w)
        x_ref, se_ref = numpy_nonnegative_fit(A, m, w)
        assert np.array_equal(x > 0.0, x_ref > 0.0)   # the same active set
        assert np.allclose(x, x_ref, rtol=1e-9, atol=1e-12 * np.max(x_ref))
        assert np.allclose(se, se_ref, rtol=1e-9)


def test_a_signal_without_noise_gives_zero_figures():
    # a lag whose squares are all zero weighs finitely (MIN_MEAN_SQUARE): the fit is zero, not an exception
    A, _, _ = meter_problem(np.random.default_rng(0), 5)
    m = np.zeros(5)
    x, se = weighted_nonnegative_fit(A, m, 1.0 / (2.0 * np.maximum(m, MIN_MEAN_SQUARE) ** 2))
    assert np.all(x == 0.0) and np.all(np.isfinite(se))


def numpy_noise_rows(sums, counts, lag_s, step_s, gravity):
    """NoiseMeter.figures' rows in numpy: the lags with their span, their design, mean squares and weights."""
    have = counts * step_s >= MIN_SPAN_S
    lag_s, counts = lag_s[have], counts[have]
    m = sums[have] / counts
    A = np.column_stack((8.0 / 3.0 * lag_s, 2.0 / 3.0 * gravity**2 * lag_s**3, 20.0 / lag_s))
    n_eff = np.maximum(counts * step_s / (2.0 * lag_s), 1.0)
    return have.sum(), A, m, n_eff / (2.0 * np.maximum(m, MIN_MEAN_SQUARE) ** 2)


@pytest.mark.parametrize("step_s", [0.1, 0.05, 0.03])
def test_the_noise_figures_are_the_fit_of_the_numpy_rows(step_s):
    rng = np.random.default_rng(round(step_s * 100))
    lag_s = np.array([max(1, round(lag / step_s)) for lag in LAGS_S]) * step_s
    for _ in range(300):
        counts = np.floor(rng.uniform(0, 2.0 * MIN_SPAN_S / step_s, len(lag_s)))
        sums = counts * 10.0 ** rng.uniform(-16, -8, len(lag_s)) * (rng.uniform(size=len(lag_s)) > 0.1)
        rows, A, m, w = numpy_noise_rows(sums, counts, lag_s, step_s, 9.8)
        figures = noise_figures(sums, counts, lag_s, lag_s**3, step_s, 9.8, MIN_SPAN_S, MIN_MEAN_SQUARE)
        if rows < 3:
            assert figures is None
            continue
        x, se = weighted_nonnegative_fit(A, m, w)
        assert figures == (*x, *se)
