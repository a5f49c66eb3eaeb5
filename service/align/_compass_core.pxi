# The compass loops' arithmetic shared by the compiled kernels: included (include "_compass_core.pxi") after
# _platform.pxi into each module that uses it. _compass.pyx's docstring describes it; the including module cimports
# ceil, cos, fabs, log2, pow, sin and sqrt from libc.math. Matrices row-major: C_{b0}^{p} 9, F, Q and P 64.


cdef inline void _mat8_mul(const double* A, const double* B, double* out) noexcept nogil:
    """out = A B of 8×8 row-major matrices, each term added in index order. The loops run i, k, j: each out[i, j]
    still sums A[i, k] B[k, j] for k = 0 … 7 in that order (the same bits), and the inner loop over j runs along
    rows, which the compiler can vectorise without reassociating a sum."""
    cdef double row[8]
    cdef double a
    cdef int i, j, k
    for i in range(8):
        for j in range(8):
            row[j] = 0.0
        for k in range(8):
            a = A[8 * i + k]
            for j in range(8):
                row[j] = row[j] + a * B[8 * k + j]
        for j in range(8):
            out[8 * i + j] = row[j]


cdef void _step(double* C_b0_p, double* V, double* I_E, double* I_N, double* y, const double* dalpha_b0,
                double dt_s, double K1L, double K2L, double K3L, bint azimuth_on, double K1A, double K2A, double K3A,
                double K4A, double earth_sign, const double* omega_ie_n, double omega_cos, double omega_sin,
                double radius_m, const double* F, const double* Q, double* P) noexcept nogil:
    """One control step (module docstring) on row-major C_{b0}^{p} (9), V (2), F, Q, P (64), in place."""
    cdef double V_E = V[0], V_N = V[1], omega_E, w_up, K1N
    cdef double H[9]
    cdef double C[9]
    cdef double HC[9]
    cdef double CCt[9]
    cdef double CCtC[9]
    cdef double Cv[3]
    cdef double dv[3]
    cdef double T[64]
    cdef double Ft[64]
    cdef double row[8]
    cdef double s
    cdef int i, j, k
    # the commanded rate from the state at the step's start, the platform rate and the half-step turn
    if azimuth_on:
        omega_E = -(1.0 + K2A) * V_N / radius_m
    else:
        omega_E = -(1.0 + K2L) * V_N / radius_m - I_N[0]
    _rotation(-0.5 * dt_s * (earth_sign * omega_ie_n[0] + omega_E),
              -0.5 * dt_s * (earth_sign * omega_ie_n[1] + ((1.0 + K2L) * V_E / radius_m + I_E[0])),
              -0.5 * dt_s * (earth_sign * omega_ie_n[2] + y[0]), H)
    for i in range(3):
        Cv[i] = C_b0_p[3 * i] * dalpha_b0[0] + C_b0_p[3 * i + 1] * dalpha_b0[1] + C_b0_p[3 * i + 2] * dalpha_b0[2]
    for i in range(3):
        dv[i] = H[3 * i] * Cv[0] + H[3 * i + 1] * Cv[1] + H[3 * i + 2] * Cv[2]
    w_up = earth_sign * omega_sin
    K1N = K1A if azimuth_on else K1L
    V[0] = V_E + dv[0] + (2.0 * w_up * V_N - K1L * V_E) * dt_s
    V[1] = V_N + dv[1] + (-2.0 * w_up * V_E - K1N * V_N) * dt_s
    I_E[0] += K3L * V_E * dt_s
    if azimuth_on:
        y[0] += (-K3A * y[0] + K4A / (earth_sign * omega_cos) * V_N) * dt_s
    else:
        I_N[0] += K3L * V_N * dt_s
    # C ← H H C, then re-orthonormalised to first order: 1.5 C − 0.5 C Cᵀ C
    _mat3_mul(H, C_b0_p, HC)
    _mat3_mul(H, HC, C)
    for i in range(3):
        for j in range(3):
            CCt[3 * i + j] = C[3 * i] * C[3 * j] + C[3 * i + 1] * C[3 * j + 1] + C[3 * i + 2] * C[3 * j + 2]
    _mat3_mul(CCt, C, CCtC)
    for i in range(3):
        for j in range(3):
            C_b0_p[3 * i + j] = 1.5 * C[3 * i + j] - 0.5 * CCtC[3 * i + j]
    # P ← F P Fᵀ + Q, the upper triangle mirrored; (F P) Fᵀ summed as _mat8_mul sums, k = 0 … 7 for each element
    _mat8_mul(F, P, T)
    for i in range(8):
        for j in range(8):
            Ft[8 * j + i] = F[8 * i + j]
    for i in range(8):
        for j in range(8):
            row[j] = 0.0
        for k in range(8):
            s = T[8 * i + k]
            for j in range(i, 8):
                row[j] = row[j] + s * Ft[8 * k + j]
        for j in range(i, 8):
            P[8 * i + j] = row[j] + Q[8 * i + j]
    for i in range(8):
        for j in range(i):
            P[8 * i + j] = P[8 * j + i]


cdef void _expm8(double* A, double* E) noexcept nogil:
    """E = exp(A) of an 8×8 row-major A (overwritten: scaled) by scaling and squaring of a Taylor series: A scaled by
    2^−s to a row-sum norm of at most 0.25, nine terms, s squarings; the products add their terms in index order."""
    cdef double norm = 0.0, row, scale
    cdef double term[64]
    cdef double nxt[64]
    cdef int squarings = 0, k, i, j
    for i in range(8):
        row = 0.0
        for j in range(8):
            row = row + fabs(A[8 * i + j])
        if row > norm:
            norm = row
    if norm > 0.25:
        squarings = <int>ceil(log2(norm / 0.25))
    scale = pow(2.0, <double>squarings)
    for i in range(64):
        A[i] = A[i] / scale
        E[i] = 1.0 if i % 9 == 0 else 0.0
        term[i] = E[i]
    for k in range(1, 10):
        _mat8_mul(term, A, nxt)
        for i in range(64):
            term[i] = nxt[i] / k
            E[i] = E[i] + term[i]
    for k in range(squarings):
        _mat8_mul(E, E, nxt)
        for i in range(64):
            E[i] = nxt[i]


cdef void _transition(double K1L, double K2L, double K3L, bint azimuth_on, double K1A, double K2A, double K3A,
                      double K4A, double earth_sign, double gravity, double radius_m, double omega_cos,
                      double omega_sin, double dt_s, double* F) noexcept nogil:
    """F (64, row-major) = exp(A Δ) of the loops' linear error model over a step of Δ seconds: A as
    ``CompassLoops.error_dynamics`` builds it for these gains (the azimuth gains read only with ``azimuth_on``) and
    Earth-rate sign, times Δ, exponentiated by :func:`_expm8`."""
    cdef double A[64]
    cdef double wc = earth_sign * omega_cos, ws = earth_sign * omega_sin
    cdef double K1N = K1A if azimuth_on else K1L
    cdef double K2N = K2A if azimuth_on else K2L
    cdef int i
    for i in range(64):
        A[i] = 0.0
    # rows and columns: δV_E, δV_N, φ_E, φ_N, φ_U, I_E, I_N, y
    A[8 * 0 + 0], A[8 * 0 + 3] = -K1L, -gravity
    A[8 * 1 + 1], A[8 * 1 + 2] = -K1N, gravity
    A[8 * 2 + 1], A[8 * 2 + 3], A[8 * 2 + 4] = -(1.0 + K2N) / radius_m, ws, -wc
    A[8 * 3 + 0], A[8 * 3 + 5], A[8 * 3 + 2] = (1.0 + K2L) / radius_m, 1.0, -ws
    A[8 * 4 + 2] = wc
    A[8 * 5 + 0] = K3L
    if azimuth_on:
        A[8 * 4 + 7] = 1.0
        A[8 * 7 + 7], A[8 * 7 + 1] = -K3A, K4A / wc
    else:
        A[8 * 2 + 6] = -1.0
        A[8 * 6 + 1] = K3L
    for i in range(64):
        A[i] = A[i] * dt_s
    _expm8(A, F)
