# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""One attitude's conversions compiled (built at install; docs/performance.md): the quaternion of a K matrix's top
eigenvector, the DCM of one quaternion, a record's angles and the output rule's turn of one attitude to another's
heading, each called once per control step or record.

The top eigenvector comes from cyclic Jacobi rotations of the symmetric 4×4 K (_linalg.pxi), run until the
off-diagonal is zero in floating point: each rotation is orthogonal to the last bit, so the eigenvector is as
accurate as LAPACK's (which ``numpy.linalg.eigh`` calls) and differs from it by rounding divided by the gap between
K's two largest eigenvalues (tests/unit/test_attitude_kernels.py). The DCM is conventions.dcm_from_quat's formula
element by element, the same bits (compiled with -ffp-contract=off: no fused multiply-adds).

The angles and the turn are the numpy functions' arithmetic in the same order, with the C library's atan2, asin,
sin and cos where numpy may take its own vectorised ones (and a sum of squares where numpy's norm and matrix
product may take BLAS's order): they differ from them by a unit or two of the last place (1e-16 rad).

Quaternions are Hamilton [w, x, y, z] with w ≥ 0, as conventions.quat_normalize gives them.
"""
from libc.math cimport M_PI, asin, atan2, cos, fabs, fmod, pow, sin, sqrt

include "_linalg.pxi"
include "_quaternion.pxi"
include "_fixed_site.pxi"
include "_platform.pxi"

import numpy as np


def quaternion_from_K(const double[:, :] K):
    """[w, x, y, z] (w ≥ 0) of the eigenvector of the symmetric K (4, 4) with the largest eigenvalue, K's rows
    ordered (x, y, z, w) as solvers.quaternion_from_K takes them."""
    cdef double k[16]
    cdef int i, j
    for i in range(4):
        for j in range(4):
            k[4 * i + j] = K[i, j]
    out = np.empty(4)
    cdef double[::1] o = out
    _top_quaternion(k, &o[0])
    return out


def dcm_from_quat_one(const double[::1] q):
    """C (3, 3) of one unit quaternion [w, x, y, z]: conventions.dcm_from_quat's formula, the same bits."""
    out = np.empty((3, 3))
    cdef double[:, ::1] C = out
    _dcm(q[0], q[1], q[2], q[3], &C[0, 0])
    return out


cdef double DEG = M_PI / 180.0
cdef double TWO_PI = 2.0 * M_PI


cdef void _shepperd(const double* M, double* q) noexcept nogil:
    """The unit quaternion (w ≥ 0) of the rotation M (row-major 9): conventions.quat_from_dcm, operation for
    operation."""
    cdef double d[4]
    cdef int i, best = 0
    d[0], d[1] = 1.0 + M[0] + M[4] + M[8], 1.0 + M[0] - M[4] - M[8]
    d[2], d[3] = 1.0 - M[0] + M[4] - M[8], 1.0 - M[0] - M[4] + M[8]
    for i in range(1, 4):
        if d[i] > d[best]:
            best = i
    if best == 0:
        q[0], q[1], q[2], q[3] = d[0], M[7] - M[5], M[2] - M[6], M[3] - M[1]
    elif best == 1:
        q[0], q[1], q[2], q[3] = M[7] - M[5], d[1], M[3] + M[1], M[2] + M[6]
    elif best == 2:
        q[0], q[1], q[2], q[3] = M[2] - M[6], M[3] + M[1], d[2], M[7] + M[5]
    else:
        q[0], q[1], q[2], q[3] = M[3] - M[1], M[2] + M[6], M[7] + M[5], d[3]
    _normalize(q)


cdef void _coarse(const double* C_n_n0, const double* q_b_n0, const double* q_b_b0, double* B,
                  double* q) noexcept nogil:
    """q (w ≥ 0) of C_b^n = C_{n0}^{n} C(q_b_n0) C(q_b_b0), C_{n0}^{n} the transpose of C_n_n0 (row-major 9): the
    coarse stage's attitude at one instant; C(q_b_b0) into B (9)."""
    cdef double T[9]
    cdef double A[9]
    cdef double P[9]
    cdef double M[9]
    cdef int i, j
    for i in range(3):
        for j in range(3):
            T[3 * i + j] = C_n_n0[3 * j + i]
    _dcm(q_b_n0[0], q_b_n0[1], q_b_n0[2], q_b_n0[3], A)
    _dcm(q_b_b0[0], q_b_b0[1], q_b_b0[2], q_b_b0[3], B)
    _mat3_mul(T, A, P)
    _mat3_mul(P, B, M)
    _shepperd(M, q)


def chained_quaternion(const double[:, :] C_n_n0, const double[::1] q_b_n0, const double[::1] q_b_b0):
    """[w, x, y, z] (w ≥ 0) of C_b^n = C_{n0}^{n} C(q_b_n0) C(q_b_b0), with C_{n0}^{n} = ``C_n_n0``ᵀ: the coarse
    stage's attitude at one instant (coarse.solution_at)."""
    cdef double C[9]
    cdef double B[9]
    cdef int i, j
    for i in range(3):
        for j in range(3):
            C[3 * i + j] = C_n_n0[i, j]
    out = np.empty(4)
    cdef double[::1] o = out
    _coarse(C, &q_b_n0[0], &q_b_b0[0], B, &o[0])
    return out


cdef tuple _angles(const double* q):
    """(q normalised as a 4-tuple, heading in [0, 360), pitch, roll), degrees, of C_b^n = C(q)."""
    cdef double C[9]
    cdef double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    _dcm(q[0], q[1], q[2], q[3], C)
    cdef double heading = atan2(C[1], C[4])
    if heading < 0.0:
        heading += TWO_PI
    cdef double heading_deg = fmod(heading / DEG, 360.0)
    cdef double c21 = 1.0 if C[7] > 1.0 else -1.0 if C[7] < -1.0 else C[7]
    return ((q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm),
            heading_deg if heading_deg < 360.0 else 0.0, asin(c21) / DEG, atan2(-C[6], C[8]) / DEG)


def record_angles(const double[::1] q):
    """A record's attitude of C_b^n = C(q) (q [w, x, y, z], near unit): (q normalised as a 4-tuple, heading in
    [0, 360), pitch, roll), degrees; conventions.euler_from_dcm of conventions.dcm_from_quat, as records.py takes it."""
    cdef double p[4]
    p[0], p[1], p[2], p[3] = q[0], q[1], q[2], q[3]
    return _angles(p)


cdef void _with_heading_of(const double* C_level, const double* C_heading, double* out) noexcept nogil:
    """out (9) = C_b^n with the tilt of ``C_level`` and the heading of ``C_heading`` (row-major 9 each): the turn about
    Up by φ_U of C_level C_headingᵀ, through Shepperd's quaternion and its rotation vector."""
    cdef double M[9]
    cdef double q[4]
    cdef int i, j
    cdef double s, angle, scale, phi_up, c, sn
    for i in range(3):
        for j in range(3):
            M[3 * i + j] = C_level[3 * i] * C_heading[3 * j] + C_level[3 * i + 1] * C_heading[3 * j + 1] + \
                C_level[3 * i + 2] * C_heading[3 * j + 2]
    _shepperd(M, q)
    _normalize(q)   # again, as rotvec_from_quat does
    s = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    angle = 2.0 * atan2(s, q[0])
    scale = angle / s if s > 1e-12 else 2.0
    phi_up = -(scale * q[3])
    c, sn = cos(phi_up), sin(phi_up)
    for j in range(3):
        out[j] = c * C_level[j] - sn * C_level[3 + j]
        out[3 + j] = sn * C_level[j] + c * C_level[3 + j]
        out[6 + j] = C_level[6 + j]


def with_heading_of_one(const double[:, :] C_level, const double[:, :] C_heading):
    """C_b^n (3, 3) with the tilt of ``C_level`` and the heading of ``C_heading``: conventions.with_heading_of."""
    cdef double L[9]
    cdef double H[9]
    cdef int i, j
    for i in range(3):
        for j in range(3):
            L[3 * i + j], H[3 * i + j] = C_level[i, j], C_heading[i, j]
    out = np.empty((3, 3))
    cdef double[:, ::1] o = out
    _with_heading_of(L, H, &o[0, 0])
    return out


def fine_record_angles(double lat, double elapsed_s, const double[::1] q_b_n0, const double[::1] q_b_b0,
                       double coarse_heading_sigma_deg, double coarse_level_sigma_deg, double fine_heading_sigma_deg,
                       double fine_level_sigma_deg, const double[:, ::1] C_b0_p, const double[::1] V, double I_E,
                       double I_N, double y, bint azimuth_on, double K2L, double K2A, double earth_sign,
                       const double[::1] omega_ie_n, double radius_m, double since_step_s):
    """A fixed-base record's attitude once the compass loops run (:func:`record_angles` of it): the coarse attitude at
    ``elapsed_s`` (C_{n0}^{n} of the fixed site, C(q_b_n0) C(q_b_b0): coarse.solution_at), the loops' (C_{b0}^{p} turned
    on for ``since_step_s`` at the commanded rate, times C(q_b_b0): CompassLoops.attitude), and the output rule
    (records.py): the level of whichever claims the smaller level σ, the heading of whichever claims the smaller
    heading σ (conventions.with_heading_of), through Shepperd's quaternion."""
    cdef double B[9]
    cdef double M[9]
    cdef double F[9]
    cdef double C[9]
    cdef double q[4]
    cdef const double* level
    cdef const double* heading
    cdef bint level_fine = fine_level_sigma_deg < coarse_level_sigma_deg
    cdef bint heading_fine = fine_heading_sigma_deg < coarse_heading_sigma_deg
    cdef int i
    _C_n_n0_fixed(lat, elapsed_s, M)
    _coarse(M, &q_b_n0[0], &q_b_b0[0], B, q)   # the coarse attitude, as its solution holds it
    if level_fine or heading_fine:
        for i in range(9):
            C[i] = C_b0_p[i // 3, i % 3]
        _platform_attitude(C, &V[0], I_E, I_N, y, azimuth_on, K2L, K2A, earth_sign, &omega_ie_n[0], radius_m,
                           since_step_s, B, F)
        if level_fine == heading_fine:
            _shepperd(F, q)
        else:
            _dcm(q[0], q[1], q[2], q[3], C)
            level, heading = (&F[0] if level_fine else &C[0]), (&F[0] if heading_fine else &C[0])
            _with_heading_of(level, heading, M)
            _shepperd(M, q)
    return _angles(q)
