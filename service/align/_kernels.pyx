# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""Compiled inner loops of the fixed-base path (built at install; docs/performance.md).

Each kernel does what the numpy expression named in its docstring does, on one epoch or one block of
observations, without the interpreter between the small-array steps. Elementwise arithmetic is written in the
order numpy evaluates it (the same libm sin and cos, no contraction into fused multiply-adds: compiled with
-ffp-contract=off), so the closed forms give numpy's bits; sums of products (dot, matmul) add their terms in index
order, where numpy's BLAS may add them in another: those agree to the last few bits (tests/unit/test_kernels.py).

Units are SI: time s, angles rad, α and β m/s; frames as in service/align/earth.py and noise_check.py.
"""
from libc.math cimport M_PI, cos, fabs, isfinite, pow, sin, sqrt

include "_linalg.pxi"
include "_quaternion.pxi"
include "_fixed_site.pxi"
include "_noise_feed.pxi"
include "_fold.pxi"
include "_policy.pxi"

import numpy as np



def beta_fixed_at(double lat, double gravity, double t):
    """β (3,) m/s at one time ``t`` (s since the start): earth.beta_fixed of a scalar, the same bits."""
    out = np.empty(3)
    cdef double[::1] o = out
    _beta_fixed(lat, gravity, t, &o[0])
    return out


def C_n_n0_fixed_at(double lat, double t):
    """C_{n(t)}^{n0} (3, 3) at one time ``t`` (s since the start)."""
    out = np.empty((3, 3))
    cdef double[:, ::1] o = out
    _C_n_n0_fixed(lat, t, &o[0, 0])
    return out


def horizontal_gained(double lat, double elapsed_s, const double[:, :] C_b0_n0, const double[:] alpha,
                      const double[:] beta, const double[:] alpha_from, const double[:] beta_from):
    """(|horizontal velocity gained| m/s, |horizontal turn of β| m/s) from the ``_from`` instant to ``elapsed_s``, in
    the navigation frame of then: C_n0^n (C_b0^n0 (α − α_from) − (β − β_from)) and C_n0^n (β − β_from)."""
    cdef double C[9]
    cdef double a[3]
    cdef double b[3]
    cdef double a_from[3]
    cdef double b_from[3]
    cdef double out[2]
    cdef int i, j
    for i in range(3):   # any strides in (the monitor may pass a transposed view): copied as they read
        for j in range(3):
            C[3 * i + j] = C_b0_n0[i, j]
        a[i], b[i], a_from[i], b_from[i] = alpha[i], beta[i], alpha_from[i], beta_from[i]
    _horizontal(lat, elapsed_s, C, a, b, a_from, b_from, out)
    return out[0], out[1]


def store_and_gain(double lat, double gravity, double elapsed_s, const double[::1] alpha_b0,
                   const double[:, ::1] C_b0_n0, double[::1] ring_elapsed, double[:, ::1] ring_alpha,
                   double[:, ::1] ring_beta, double[:, :, ::1] ring_C, Py_ssize_t slot, Py_ssize_t oldest,
                   bint gain):
    """One motion check's entry into the monitor's ring at ``slot``: the time (s), α (3,) m/s in b0 axes, β of the
    fixed site there (:func:`beta_fixed_at`) and C_b0^n0 (3, 3); with ``gain``, the horizontal velocity (m/s) gained
    since the entry at ``oldest`` under that entry's C_b0^n0 (:func:`horizontal_gained`), else NaN."""
    cdef int i, j
    cdef double out[2]
    ring_elapsed[slot] = elapsed_s
    _beta_fixed(lat, gravity, elapsed_s, &ring_beta[slot, 0])
    for i in range(3):
        ring_alpha[slot, i] = alpha_b0[i]
        for j in range(3):
            ring_C[slot, i, j] = C_b0_n0[i, j]
    if not gain:
        return float("nan")
    _horizontal(lat, elapsed_s, &ring_C[oldest, 0, 0], &ring_alpha[slot, 0], &ring_beta[slot, 0],
                &ring_alpha[oldest, 0], &ring_beta[oldest, 0], out)
    return out[0]


def hadamard_feed(double lat, double gravity, const double[::1] elapsed_s, const double[:, ::1] alpha_b0,
                  double[:, ::1] alpha_sum, double[:, ::1] beta_sum, double[::1] moments,
                  const long[::1] lags, double[::1] sums, double[::1] counts, C_n0_b0, long steps, long bad_until,
                  long settle_steps, double outlier_factor, long min_outlier_count, long verdict_steps):
    """NoiseMeter.feed's loop over a block's observations (elapsed (M,) s, α (M, 3) m/s in b0 axes), updating the
    meter's rings and sums in place; returns (steps, bad_until, outliers found, whether a step count that is a
    multiple of ``verdict_steps`` was reached)."""
    cdef double C[9]
    cdef const double[:, :] C_view
    cdef int i, j
    cdef bint verdict_due = False
    cdef long outliers, count = elapsed_s.shape[0]
    if alpha_b0.shape[0] != count or alpha_sum.shape[0] != beta_sum.shape[0] or moments.shape[0] != 23 \
            or sums.shape[0] != lags.shape[0] or counts.shape[0] != lags.shape[0]:
        raise ValueError("hadamard_feed: one α row per time, rings of one capacity, one sum and count per lag")
    if C_n0_b0 is not None:   # any strides in (the meter is given a transposed view): copied as they read
        C_view = C_n0_b0
        for i in range(3):
            for j in range(3):
                C[3 * i + j] = C_view[i, j]
    if count == 0:
        return steps, bad_until, 0, False
    outliers = _hadamard_feed(lat, gravity, &elapsed_s[0], &alpha_b0[0, 0], count, &alpha_sum[0, 0],
                              &beta_sum[0, 0], alpha_sum.shape[0], &moments[0], &lags[0], lags.shape[0],
                              &sums[0], &counts[0], C if C_n0_b0 is not None else NULL, &steps, &bad_until,
                              settle_steps, outlier_factor, min_outlier_count, verdict_steps, &verdict_due)
    return steps, bad_until, outliers, verdict_due


cdef bint _subset_least_squares(int rows, int k, const double* Aw, const int* cols, const double* mw,
                                double* x) noexcept nogil:
    """x (k,) minimising |Aw[:, cols] x − mw| (Aw row-major (rows, 3)) by Householder QR; False where the columns
    are dependent (a diagonal of R below the rounding of the largest)."""
    cdef double R[8 * 3]
    cdef double b[8]
    cdef double norm, alpha, vnorm2, dot, largest = 0.0
    cdef int i, j, c
    for i in range(rows):
        b[i] = mw[i]
        for j in range(k):
            R[k * i + j] = Aw[3 * i + cols[j]]
    for j in range(k):
        norm = 0.0
        for i in range(j, rows):
            norm += R[k * i + j] * R[k * i + j]
        norm = sqrt(norm)
        if norm == 0.0:
            return False
        alpha = -norm if R[k * j + j] > 0.0 else norm
        R[k * j + j] -= alpha   # the reflector v = column j − α e_j, kept in place
        vnorm2 = 0.0
        for i in range(j, rows):
            vnorm2 += R[k * i + j] * R[k * i + j]
        for c in range(j + 1, k):
            dot = 0.0
            for i in range(j, rows):
                dot += R[k * i + j] * R[k * i + c]
            for i in range(j, rows):
                R[k * i + c] -= 2.0 * dot / vnorm2 * R[k * i + j]
        dot = 0.0
        for i in range(j, rows):
            dot += R[k * i + j] * b[i]
        for i in range(j, rows):
            b[i] -= 2.0 * dot / vnorm2 * R[k * i + j]
        R[k * j + j] = alpha
        largest = max(largest, fabs(alpha))
    for j in range(k - 1, -1, -1):
        if fabs(R[k * j + j]) <= 1e-15 * rows * largest:
            return False
        dot = b[j]
        for c in range(j + 1, k):
            dot -= R[k * j + c] * x[c]
        x[j] = dot / R[k * j + j]
    return True


cdef inline bint _any_negative(const double* x, int k) noexcept nogil:
    cdef int j
    for j in range(k):
        if x[j] < 0.0:
            return True
    return False


cdef void _nonnegative_fit(int rows, const double* A, const double* m, const double* weights, double* best,
                           double* se) noexcept nogil:
    """:func:`weighted_nonnegative_fit` on a row-major A (rows ≤ 8, 3): x ≥ 0 into ``best``, the standard errors
    into ``se``."""
    cdef int i, j, c, k
    cdef double Aw[8 * 3]
    cdef double mw[8]
    cdef double N[9]
    cdef double V[9]
    cdef double scale[3]
    cdef double x_sub[3]
    cdef double x[3]
    cdef double best_cost = 0.0, cost, r, root, largest = 0.0, diagonal
    cdef int subsets[7][3]
    cdef int sizes[7]
    sizes[:] = [1, 1, 1, 2, 2, 2, 3]   # itertools.combinations(range(3), size) for size 1, 2, 3
    subsets[0][:] = [0, 0, 0]
    subsets[1][:] = [1, 0, 0]
    subsets[2][:] = [2, 0, 0]
    subsets[3][:] = [0, 1, 0]
    subsets[4][:] = [0, 2, 0]
    subsets[5][:] = [1, 2, 0]
    subsets[6][:] = [0, 1, 2]
    for i in range(rows):
        root = sqrt(weights[i])
        mw[i] = m[i] * root
        best_cost += mw[i] * mw[i]
        for j in range(3):
            Aw[3 * i + j] = A[3 * i + j] * root
    for j in range(3):
        best[j] = 0.0
        for c in range(3):
            N[3 * j + c] = 0.0
            for i in range(rows):
                N[3 * j + c] += Aw[3 * i + j] * Aw[3 * i + c]
    for j in range(3):
        scale[j] = sqrt(N[4 * j])
    for j in range(3):
        for c in range(3):
            N[3 * j + c] = N[3 * j + c] / (scale[j] * scale[c])
    for k in range(7):
        if not _subset_least_squares(rows, sizes[k], Aw, subsets[k], mw, x_sub) or _any_negative(x_sub, sizes[k]):
            continue
        for j in range(3):
            x[j] = 0.0
        for j in range(sizes[k]):
            x[subsets[k][j]] = x_sub[j]
        cost = 0.0
        for i in range(rows):
            r = Aw[3 * i] * x[0] + Aw[3 * i + 1] * x[1] + Aw[3 * i + 2] * x[2] - mw[i]
            cost += r * r
        if cost < best_cost:
            best_cost = cost
            best[0], best[1], best[2] = x[0], x[1], x[2]
    jacobi_eigen(3, N, V)
    for j in range(3):
        largest = max(largest, fabs(N[4 * j]))
    for j in range(3):
        diagonal = 0.0
        for c in range(3):
            if fabs(N[4 * c]) > 1e-15 * largest:
                diagonal += V[3 * j + c] * V[3 * j + c] / N[4 * c]
        se[j] = sqrt(max(diagonal / (scale[j] * scale[j]), 0.0))


def weighted_nonnegative_fit(const double[:, ::1] A, const double[::1] m, const double[::1] weights):
    """noise_check's fit, for 3 unknowns and at most 8 rows: x ≥ 0 minimising Σ w (A x − m)² over the 7 active sets
    (sizes 1 to 3, each solved by Householder QR), and the standard errors of the unconstrained fit, the diagonal of
    the pseudo-inverse of the column-scaled normal matrix (eigenvalues below 1e-15 of the largest left out, as
    numpy.linalg.pinv does). Returns (x (3,), standard errors (3,))."""
    if A.shape[0] > 8 or A.shape[1] != 3 or m.shape[0] != A.shape[0] or weights.shape[0] != A.shape[0]:
        raise ValueError("weighted_nonnegative_fit takes A (rows ≤ 8, 3), m and weights (rows,)")
    x, se = np.empty(3), np.empty(3)
    cdef double[::1] x_view = x, se_view = se
    _nonnegative_fit(A.shape[0], &A[0, 0], &m[0], &weights[0], &x_view[0], &se_view[0])
    return x, se


def noise_figures(const double[::1] sums, const double[::1] counts, const double[::1] lag_s,
                  const double[::1] lag_cubed, double step_s, double gravity, double min_span_s,
                  double min_mean_square):
    """NoiseMeter.figures: each lag τ (``lag_s``, with τ³ as the meter computed it once) with ``min_span_s`` of
    stencils (counts × step ≥ it) gives its mean square m = sum / count, its row (8/3 τ, 2/3 g² τ³, 20 / τ) and
    its weight n_eff / (2 max(m, ``min_mean_square``)²), n_eff = max(count × step / (2 τ), 1); the fit of :func:`weighted_nonnegative_fit`. Returns (q, N², S, their
    standard errors), or None before three lags have their span."""
    cdef int n = sums.shape[0], rows = 0, j
    cdef double A[8 * 3]
    cdef double m[8]
    cdef double w[8]
    cdef double x[3]
    cdef double se[3]
    cdef double lag, mean, n_eff, floor_m
    cdef double cubic = 2.0 / 3.0 * pow(gravity, 2.0)
    if n > 8 or counts.shape[0] != n or lag_s.shape[0] != n or lag_cubed.shape[0] != n:
        raise ValueError("noise_figures: at most 8 lags, one sum, count and lag each")
    for j in range(n):
        if counts[j] * step_s >= min_span_s:
            lag = lag_s[j]
            mean = sums[j] / counts[j]
            A[3 * rows], A[3 * rows + 1], A[3 * rows + 2] = 8.0 / 3.0 * lag, cubic * lag_cubed[j], 20.0 / lag
            n_eff = max(counts[j] * step_s / (2.0 * lag), 1.0)
            floor_m = max(mean, min_mean_square)
            m[rows], w[rows] = mean, n_eff / (2.0 * (floor_m * floor_m))
            rows += 1
    if rows < 3:
        return None
    _nonnegative_fit(rows, A, m, w, x, se)
    return x[0], x[1], x[2], se[0], se[1], se[2]


cdef inline void _earth_turn_integrals(double t, double* out) noexcept nogil:
    """earth.earth_turn_integrals of a scalar: (sin Ωt / Ω, (1 − cos Ωt) / Ω, t − sin Ωt / Ω) s."""
    cdef double wt = OMEGA_IE * t, wt2 = wt * wt, s_half = sin(0.5 * wt)
    out[0] = sin(wt) / OMEGA_IE
    out[1] = 2.0 * (s_half * s_half) / OMEGA_IE
    if wt > 1e-3:
        out[2] = t - sin(wt) / OMEGA_IE
    else:
        out[2] = t * wt2 / 6.0 * (1.0 - wt2 / 20.0 + wt2 * wt2 / 840.0)


cdef inline double _at_least(double x, double floor) noexcept nogil:
    """numpy.maximum(x, floor) for a finite floor: NaN stays NaN."""
    return floor if x < floor else x


def swing_normal_equations(const double[:] elapsed_s, const double[:, :] q_b_b0, const double[:, :] alpha,
                           double vrw2, double t_last, const double[:] basis_last, const double[:] alpha_last,
                           const double[:, :] C_last, const double[:, :] M_last, const double[:, :] normal_last,
                           const double[:] rhs_last, double ridge):
    """SwingBias.correct's sums over K observations (elapsed (K,) s, C_b^b0 (K, 4), α (K, 3) m/s) from the fit's
    state at the last one: for each, the equilibrated normal system of the fit up to it, ready for the solve
    (matrix with the ``ridge`` on its diagonal (K, 12, 12), right side (K, 12), the scale (K, 12) that takes its solution back to the
    parameters), M(t) (K, 3, 3) and E(t)'s integrals (K, 3); then the new state's C_b^b0 (3, 3), normal matrix
    (12, 12) and right side (12,). swing_bias.py's numpy form operation for operation: the same bits."""
    cdef long n = elapsed_s.shape[0], k, r, c, i, j
    scaled_out = np.empty((n, 12, 12))
    scaled_rhs_out = np.empty((n, 12))
    scale_out = np.empty((n, 12))
    M_out = np.empty((n, 3, 3))
    basis_out = np.empty((n, 3))
    C_out = np.empty((3, 3))
    normal_out = np.empty((12, 12))
    rhs_out = np.empty(12)
    cdef double[:, :, ::1] scaled = scaled_out
    cdef double[:, ::1] scaled_rhs = scaled_rhs_out
    cdef double[:, ::1] scale = scale_out
    cdef double[:, :, ::1] Ms = M_out
    cdef double[:, ::1] basis = basis_out
    cdef double[:, ::1] normal = normal_out
    cdef double[::1] rhs = rhs_out
    cdef double[:, ::1] C_last_out = C_out
    cdef double C_prev[9]
    cdef double C[9]
    cdef double M[9]
    cdef double dM[9]
    cdef double basis_prev[3]
    cdef double alpha_prev[3]
    cdef double dalpha[3]
    cdef double X[3 * 12]
    cdef double t_prev = t_last, dt, weight, XtX, Xtz
    for i in range(3):
        basis_prev[i], alpha_prev[i] = basis_last[i], alpha_last[i]
        for j in range(3):
            C_prev[3 * i + j], M[3 * i + j] = C_last[i, j], M_last[i, j]
    for i in range(12):
        rhs[i] = rhs_last[i]
        for j in range(12):
            normal[i, j] = normal_last[i, j]
    for k in range(n):
        dt = elapsed_s[k] - t_prev
        _dcm(q_b_b0[k, 0], q_b_b0[k, 1], q_b_b0[k, 2], q_b_b0[k, 3], C)
        _earth_turn_integrals(elapsed_s[k], &basis[k, 0])
        for i in range(9):
            dM[i] = 0.5 * dt * (C_prev[i] + C[i])
            M[i] = M[i] + dM[i]
        # the increment's design rows [ΔP1 I, ΔP2 I, ΔP3 I, ΔM] (3, 12), the identity's zeros multiplied as numpy does
        for r in range(3):
            for i in range(3):
                for c in range(3):
                    X[12 * r + 3 * i + c] = (basis[k, i] - basis_prev[i]) * (1.0 if r == c else 0.0)
            for c in range(3):
                X[12 * r + 9 + c] = dM[3 * r + c]
            dalpha[r] = alpha[k, r] - alpha_prev[r]
        weight = 1.0 / _at_least(vrw2 * dt, 1e-300)
        for i in range(12):
            for j in range(12):
                # numpy's sum() of the three rows starts from the integer 0: 0 + (−0.0) is +0.0
                XtX = 0.0 + X[i] * X[j] + X[12 + i] * X[12 + j] + X[24 + i] * X[24 + j]
                normal[i, j] = normal[i, j] + weight * XtX
            Xtz = 0.0 + X[i] * dalpha[0] + X[12 + i] * dalpha[1] + X[24 + i] * dalpha[2]
            rhs[i] = rhs[i] + weight * Xtz
        for i in range(12):
            scale[k, i] = 1.0 / sqrt(_at_least(normal[i, i], 1e-300))
        for i in range(12):
            for j in range(12):
                scaled[k, i, j] = normal[i, j] * scale[k, i] * scale[k, j] + (ridge if i == j else 0.0)
            scaled_rhs[k, i] = scale[k, i] * rhs[i]
        for i in range(9):
            C_prev[i] = C[i]
            Ms[k, i // 3, i % 3] = M[i]
        for i in range(3):
            basis_prev[i], alpha_prev[i] = basis[k, i], alpha[k, i]
        t_prev = elapsed_s[k]
    for i in range(9):
        C_last_out[i // 3, i % 3] = C_prev[i]
    return scaled_out, scaled_rhs_out, scale_out, M_out, basis_out, C_out, normal_out, rhs_out


cdef void _earth_axis(const double* params, double lat_sign, double* w) noexcept nogil:
    """w (3,) from the fitted b, c of ``params`` (12,): c = w × b, |w| = 1, the latitude's sign settling its part
    along b; 0 where it is not finite (no fit yet): swing_bias's earth_axis form, the same bits."""
    cdef const double* b = params
    cdef const double* c = params + 3
    cdef double b2 = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
    cdef double inner = 1.0 - (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) / b2
    cdef double along = lat_sign * sqrt(0.0 if inner < 0.0 else inner), root_b2 = sqrt(b2), norm
    cdef double bc[3]
    cdef int i
    _cross(b, c, bc)
    for i in range(3):
        w[i] = bc[i] / b2 + along * b[i] / root_b2
    norm = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    for i in range(3):
        w[i] = w[i] / norm
    if not (isfinite(w[0]) and isfinite(w[1]) and isfinite(w[2])):
        w[0] = w[1] = w[2] = 0.0


def earth_axis(const double[:] params, double lat_sign):
    """The Earth axis w (3,) in b0 axes from the swing-bias fit's ``params`` (12,): c = w × b (0: no fit)."""
    out = np.empty(3)
    cdef double[::1] w = out
    cdef double p[12]
    cdef int i
    for i in range(12):
        p[i] = params[i]
    _earth_axis(p, lat_sign, &w[0])
    return out


def swing_corrected(const double[:, :] alpha, const double[:, :, :] M, const double[:, :] basis,
                    const double[:, :] params, double lat_sign):
    """α (K, 3) m/s less D(t)∇̂ = M(t)∇̂ − (P1 I + P2 [w×] + P3 w wᵀ)∇̂ at each of K observations, each with the
    fit's parameters (K, 12) up to it: swing_bias's numpy form, the same bits."""
    cdef long n = alpha.shape[0], k
    cdef int i
    cdef double p[12]
    cdef double w[3]
    cdef double wn[3]
    cdef double along, static, term
    cdef const double* nabla = p + 9
    out = np.empty((n, 3))
    cdef double[:, ::1] o = out
    for k in range(n):
        for i in range(12):
            p[i] = params[k, i]
        _earth_axis(p, lat_sign, w)
        _cross(w, nabla, wn)
        along = w[0] * nabla[0] + w[1] * nabla[1] + w[2] * nabla[2]
        for i in range(3):
            static = basis[k, 0] * nabla[i] + basis[k, 1] * wn[i] + basis[k, 2] * (along * w[i])
            term = M[k, i, 0] * nabla[0] + M[k, i, 1] * nabla[1] + M[k, i, 2] * nabla[2] - static
            o[k, i] = alpha[k, i] - term
    return out


def beta_fixed_many(double lat, double gravity, const double[:] elapsed_s):
    """β (M, 3) m/s at M times (s since the start): earth.beta_fixed of an array, the same bits."""
    cdef long n = elapsed_s.shape[0], k
    out = np.empty((n, 3))
    cdef double[:, ::1] o = out
    for k in range(n):
        _beta_fixed(lat, gravity, elapsed_s[k], &o[k, 0])
    return out


cdef inline double _einsum_dot3(const double* a) noexcept nogil:
    """numpy.einsum("mi,mi->m") of one row of 3: its two-lane SIMD loop adds the squares as (a0² + a2²) + a1²."""
    return a[0] * a[0] + a[2] * a[2] + a[1] * a[1]


def recursive_k_prepare(const double[:, :] b, const double[:, :] r, const double[:] mu):
    """RecursiveK.prepare of M pairs (b, r (M, 3), any length; μ (M,) rad²): the pairs normalised, δK (M, 4, 4) =
    solvers.delta_K and tr R (M,) = the trace of solvers.request_noise, each operation in numpy's order: the same
    bits."""
    cdef long n = b.shape[0], k
    cdef int i, j
    cdef double bu[3]
    cdef double ru[3]
    cdef double B[9]
    cdef double z[3]
    cdef double norm_b, norm_r, sigma, scale
    dK_out = np.empty((n, 4, 4))
    trace_out = np.empty(n)
    cdef double[:, :, ::1] dK = dK_out
    cdef double[::1] trace_R = trace_out
    for k in range(n):
        for i in range(3):
            bu[i], ru[i] = b[k, i], r[k, i]
        norm_b, norm_r = sqrt(_einsum_dot3(bu)), sqrt(_einsum_dot3(ru))
        for i in range(3):
            bu[i], ru[i] = bu[i] / norm_b, ru[i] / norm_r
        scale = mu[k] * (3.0 - _einsum_dot3(bu)) * _einsum_dot3(ru)
        trace_R[k] = scale * 1.0 + scale * 1.0 + scale * 1.0 + scale * 1.0   # tr(scale I₄), numpy's terms
        for i in range(3):
            for j in range(3):
                B[3 * i + j] = bu[i] * ru[j]
        # solvers.davenport: [[B + Bᵀ − σ I, z], [zᵀ, σ]], σ = tr B
        sigma = B[0] + B[4] + B[8]
        for i in range(3):
            for j in range(3):
                dK[k, i, j] = B[3 * i + j] + B[3 * j + i] - sigma * (1.0 if i == j else 0.0)
        z[0], z[1], z[2] = B[5] - B[7], B[6] - B[2], B[1] - B[3]
        for i in range(3):
            dK[k, i, 3] = z[i]
            dK[k, 3, i] = z[i]
        dK[k, 3, 3] = sigma
    return dK_out, trace_out


def recursive_k_fold(const double[:, ::1] K, const double[:, :, ::1] dK, const double[::1] trace_R, double m,
                     double trace_P, long n, double rho, double trace_Q, int policy, double fixed_rho):
    """:meth:`RecursiveK.fold` of the prepared observations (δK (M, 4, 4), tr R (M,)) in order: K ← a K + c δK with
    the gain of ``policy`` (0 OPREQ's ρ*, 1 REQUEST's fixed ρ, 2 the q-method's 1/(n + 1)), the scalars in Python's
    order, K elementwise as numpy's (the same bits). Returns (K, m, tr P, n, ρ), K a new (4, 4) array."""
    cdef Py_ssize_t count = trace_R.shape[0]
    if dK.shape[0] != count or dK.shape[1] != 4 or dK.shape[2] != 4 or K.shape[0] != 4 or K.shape[1] != 4:
        raise ValueError("recursive_k_fold: K (4, 4), dK (M, 4, 4) and trace_R (M,)")
    K_out = np.array(K, dtype=float, copy=True)
    cdef double[:, ::1] Kn = K_out
    if count:
        _fold(&Kn[0, 0], &dK[0, 0, 0], &trace_R[0], count, &m, &trace_P, &n, &rho, trace_Q, policy, fixed_rho)
    return K_out, m, trace_P, n, rho


def coarse_variances(const double[::1] terms, double efficiency, const double[::1] elapsed_s):
    """The coarse stage's σ model (_policy.pxi ``_coarse_variances``: the rule the compiled hand-over test applies):
    heading² and level² (rad², each (N,)) after each of ``elapsed_s`` (N,) s, all positive, of a grade's and site's
    ``terms`` (sensor_model._SigmaTerms.kernel)."""
    cdef Py_ssize_t n = elapsed_s.shape[0], k
    if terms.shape[0] != COARSE_TERMS:
        raise ValueError(f"coarse_variances: {COARSE_TERMS} terms")
    heading_out, level_out = np.empty(n), np.empty(n)
    cdef double[::1] heading2 = heading_out, level2 = level_out
    for k in range(n):
        _coarse_variances(&terms[0], efficiency, elapsed_s[k], &heading2[k], &level2[k])
    return heading_out, level_out


def coarse_variances_one(const double[::1] terms, double efficiency, double elapsed_s) -> tuple:
    """:func:`coarse_variances` at one time ``elapsed_s`` > 0 s: (heading², level²) rad²."""
    cdef double heading2, level2
    if terms.shape[0] != COARSE_TERMS:
        raise ValueError(f"coarse_variances_one: {COARSE_TERMS} terms")
    _coarse_variances(&terms[0], efficiency, elapsed_s, &heading2, &level2)
    return heading2, level2


def turning_bias_rows(const double[:, ::1] C_b0_n0, const double[:, ::1] tM, const double[:, ::1] t2M,
                      const double[::1] tP, const double[::1] t2P, const double[:, :, ::1] earth, double T,
                      double heading_gain, double gravity) -> tuple:
    """turning_bias.TurningBiasTerm.variances' rows: with S = C_b0^n0 Σ t^k M Δt − (Σ t^k P_j Δt E_j) C_b0^n0 (k = 1,
    2; E_j = I, [u×], u uᵀ in ``earth``), the heading row gain (2 / (g Ω cos L)) (−60 S1_N / T⁴ + 80 S2_N / T⁵) and
    the tilt rows (48 S1_{E,N} / T³ − 60 S2_{E,N} / T⁴) / g; returns (|heading row|², the larger |tilt row|²) in
    rad² per (m/s²)²."""
    cdef double S1[2][3]
    cdef double S2[2][3]
    cdef double E1, E2, h, tilt, heading2 = 0.0, tilt2[2]
    cdef int r, c, k
    for r in range(2):   # the east and north rows
        for c in range(3):
            S1[r][c] = 0.0
            S2[r][c] = 0.0
            for k in range(3):
                E1 = tP[0] * earth[0, r, k] + tP[1] * earth[1, r, k] + tP[2] * earth[2, r, k]
                E2 = t2P[0] * earth[0, r, k] + t2P[1] * earth[1, r, k] + t2P[2] * earth[2, r, k]
                S1[r][c] += C_b0_n0[r, k] * tM[k, c] - E1 * C_b0_n0[k, c]
                S2[r][c] += C_b0_n0[r, k] * t2M[k, c] - E2 * C_b0_n0[k, c]
    tilt2[0] = tilt2[1] = 0.0
    for c in range(3):
        h = heading_gain * (-60.0 * S1[1][c] / pow(T, 4.0) + 80.0 * S2[1][c] / pow(T, 5.0))
        heading2 += h * h
        for r in range(2):
            tilt = (48.0 * S1[r][c] / pow(T, 3.0) - 60.0 * S2[r][c] / pow(T, 4.0)) / gravity
            tilt2[r] += tilt * tilt
    return heading2, max(tilt2[0], tilt2[1])
