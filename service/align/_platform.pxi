# The compass platform's turn and the attitude it gives between two control steps, shared by the compiled kernels:
# included (include "_platform.pxi") into each module that uses it (before _compass_core.pxi). The including module
# cimports cos, pow, sin and sqrt from libc.math. Matrices row-major 9; rates rad/s; frames as in compass.py.


cdef void _rotation(double x, double y, double z, double* R) noexcept nogil:
    """exp([φ×]) row-major into R[9] for φ = (x, y, z): compass.rotation_matrix."""
    cdef double angle = sqrt(x * x + y * y + z * z)
    cdef double S[9]
    cdef double SS[9]
    cdef double a, b
    cdef int i, j
    S[0] = 0.0
    S[1] = -z
    S[2] = y
    S[3] = z
    S[4] = 0.0
    S[5] = -x
    S[6] = -y
    S[7] = x
    S[8] = 0.0
    for i in range(3):
        for j in range(3):
            SS[3 * i + j] = S[3 * i] * S[j] + S[3 * i + 1] * S[3 + j] + S[3 * i + 2] * S[6 + j]
    if angle < 1e-8:
        a, b = 1.0, 0.5
    else:
        a, b = sin(angle) / angle, (1.0 - cos(angle)) / pow(angle, 2.0)
    for i in range(9):
        R[i] = (1.0 if i % 4 == 0 else 0.0) + a * S[i] + b * SS[i]


cdef inline void _mat3_mul(const double* A, const double* B, double* out) noexcept nogil:
    cdef int i, j
    for i in range(3):
        for j in range(3):
            out[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j]


cdef void _platform_attitude(const double* C_b0_p, const double* V, double I_E, double I_N, double y, bint azimuth_on,
                             double K2L, double K2A, double earth_sign, const double* omega_ie_n, double radius_m,
                             double since_step_s, const double* C_b_b0, double* out) noexcept nogil:
    """out = exp(−[ω_p t ×]) C_{b0}^{p} C_{b}^{b0}: the loops' attitude ``since_step_s`` (t) after their last step,
    the platform turned on at the rate the state commands, ω_p = s ω_ie^n + ω_c (the azimuth gain K2A read only with
    ``azimuth_on``)."""
    cdef double V_E = V[0], V_N = V[1], omega_E
    cdef double R[9]
    cdef double RC[9]
    if azimuth_on:
        omega_E = -(1.0 + K2A) * V_N / radius_m
    else:
        omega_E = -(1.0 + K2L) * V_N / radius_m - I_N
    _rotation(-since_step_s * (earth_sign * omega_ie_n[0] + omega_E),
              -since_step_s * (earth_sign * omega_ie_n[1] + ((1.0 + K2L) * V_E / radius_m + I_E)),
              -since_step_s * (earth_sign * omega_ie_n[2] + y), R)
    _mat3_mul(R, C_b0_p, RC)
    _mat3_mul(RC, C_b_b0, out)
