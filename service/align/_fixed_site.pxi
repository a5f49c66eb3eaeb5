# The fixed site's closed forms shared by the compiled kernels: included (include "_fixed_site.pxi") into each module
# that uses them, as _linalg.pxi is. β(t) and C_{n(t)}^{n0} are earth.py's forms of a scalar, the same bits; the
# velocity a base gained is disturbance.py's. The including module cimports cos, sin and sqrt from libc.math.
# Time s since the start, lat rad, β and α m/s, matrices row-major 9.

cdef double OMEGA_IE = 7.2921151467e-5   # service/align/earth.OMEGA_IE (rad/s)


cdef inline void _beta_fixed(double lat, double gravity, double t, double* out) noexcept nogil:
    cdef double wt = OMEGA_IE * t
    cdef double cL = cos(lat), sL = sin(lat), t_minus_sin, s_half
    if wt > 1e-3:
        t_minus_sin = t - sin(wt) / OMEGA_IE
    else:
        t_minus_sin = t * (wt * wt) / 6.0 * (1.0 - (wt * wt) / 20.0 + (wt * wt) * (wt * wt) / 840.0)
    s_half = sin(0.5 * wt)
    out[0] = gravity * (cL * (2.0 * (s_half * s_half) / OMEGA_IE))
    out[1] = gravity * (sL * cL * t_minus_sin)
    out[2] = gravity * (t - (cL * cL) * t_minus_sin)


cdef inline void _C_n_n0_fixed(double lat, double t, double* C) noexcept nogil:
    """C_{n(t)}^{n0} row-major into C[9]: earth.C_n_n0_fixed of a scalar, the same bits."""
    cdef double theta = OMEGA_IE * t
    cdef double c = cos(theta), s = sin(theta), u1 = cos(lat), u2 = sin(lat), v = 1.0 - c
    # c I + s [u×] + (1 − c) u uᵀ with u = (0, cos L, sin L): numpy's sum of the three terms (its zeros dropped)
    C[0] = c
    C[1] = s * -u2
    C[2] = s * u1
    C[3] = s * u2
    C[4] = c + v * (u1 * u1)
    C[5] = v * (u1 * u2)
    C[6] = s * -u1
    C[7] = v * (u2 * u1)
    C[8] = c + v * (u2 * u2)


cdef void _horizontal(double lat, double elapsed_s, const double* C_b0_n0, const double* alpha, const double* beta,
                      const double* alpha_from, const double* beta_from, double* out) noexcept nogil:
    """out = (|horizontal velocity gained|, |horizontal turn of β|) (m/s): :func:`horizontal_gained` on row-major
    C_b0^n0 (9) and 3-vectors."""
    cdef double C[9]
    cdef double dalpha[3]
    cdef double dbeta[3]
    cdef double moved[3]
    cdef double gained[2]
    cdef double turn[2]
    cdef int i
    _C_n_n0_fixed(lat, elapsed_s, C)
    for i in range(3):
        dalpha[i] = alpha[i] - alpha_from[i]
        dbeta[i] = beta[i] - beta_from[i]
    for i in range(3):
        moved[i] = C_b0_n0[3 * i] * dalpha[0] + C_b0_n0[3 * i + 1] * dalpha[1] + C_b0_n0[3 * i + 2] * dalpha[2] \
            - dbeta[i]
    for i in range(2):   # row i of C_n0^n is column i of C_n^n0
        gained[i] = C[i] * moved[0] + C[3 + i] * moved[1] + C[6 + i] * moved[2]
        turn[i] = C[i] * dbeta[0] + C[3 + i] * dbeta[1] + C[6 + i] * dbeta[2]
    out[0] = sqrt(gained[0] * gained[0] + gained[1] * gained[1])
    out[1] = sqrt(turn[0] * turn[0] + turn[1] * turn[1])
