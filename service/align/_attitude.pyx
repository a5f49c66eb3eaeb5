# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""One attitude's conversions compiled (built at install; docs/performance.md): the quaternion of a K matrix's top
eigenvector and the DCM of one quaternion, each called once per control step or record.

The top eigenvector comes from cyclic Jacobi rotations of the symmetric 4×4 K, run until the off-diagonal is zero
in floating point: each rotation is orthogonal to the last bit, so the eigenvector is as accurate as LAPACK's (which
``numpy.linalg.eigh`` calls) and differs from it by rounding divided by the gap between K's two largest
eigenvalues (tests/unit/test_attitude_kernels.py). The DCM is conventions.dcm_from_quat's formula element by element,
the same bits (compiled with -ffp-contract=off: no fused multiply-adds).

Quaternions are Hamilton [w, x, y, z] with w ≥ 0, as conventions.quat_normalize gives them.
"""
from libc.math cimport fabs, sqrt

import numpy as np

cdef int MAX_SWEEPS = 60


cdef void _rotate(double* A, double* V, int p, int q) noexcept nogil:
    """One Jacobi rotation of the 4×4 A (row-major, symmetric) that zeroes A[p, q]; V accumulates it."""
    cdef double apq = A[4 * p + q], theta, t, c, s, akp, akq
    cdef int k
    theta = (A[4 * q + q] - A[4 * p + p]) / (2.0 * apq)
    if fabs(theta) > 1e150:   # θ² would overflow: t = 1 / (2θ) to first order
        t = 0.5 / theta
    else:
        t = 1.0 / (fabs(theta) + sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / sqrt(t * t + 1.0)
    s = t * c
    for k in range(4):
        akp, akq = A[4 * k + p], A[4 * k + q]
        A[4 * k + p] = c * akp - s * akq
        A[4 * k + q] = s * akp + c * akq
    for k in range(4):
        akp, akq = A[4 * p + k], A[4 * q + k]
        A[4 * p + k] = c * akp - s * akq
        A[4 * q + k] = s * akp + c * akq
    A[4 * p + q] = A[4 * q + p] = 0.0
    for k in range(4):
        akp, akq = V[4 * k + p], V[4 * k + q]
        V[4 * k + p] = c * akp - s * akq
        V[4 * k + q] = s * akp + c * akq


def quaternion_from_K(const double[:, :] K):
    """[w, x, y, z] (w ≥ 0) of the eigenvector of the symmetric K (4, 4) with the largest eigenvalue, K's rows
    ordered (x, y, z, w) as solvers.quaternion_from_K takes them."""
    cdef double A[16]
    cdef double V[16]
    cdef double off, scale, w, x, y, z, norm
    cdef int i, j, p, q, sweep, top
    for i in range(4):
        for j in range(4):
            A[4 * i + j] = 0.5 * (K[i, j] + K[j, i])
            V[4 * i + j] = 1.0 if i == j else 0.0
    for sweep in range(MAX_SWEEPS):
        off = 0.0
        scale = 0.0
        for p in range(4):
            scale += fabs(A[5 * p])
            for q in range(p + 1, 4):
                off += fabs(A[4 * p + q])
        if off == 0.0 or off <= 1e-300 * scale:
            break
        for p in range(4):
            for q in range(p + 1, 4):
                # an element below the last place of both diagonal terms is zero already: set it so
                if fabs(A[5 * p]) + 1e3 * fabs(A[4 * p + q]) == fabs(A[5 * p]) and \
                        fabs(A[5 * q]) + 1e3 * fabs(A[4 * p + q]) == fabs(A[5 * q]):
                    A[4 * p + q] = A[4 * q + p] = 0.0
                elif A[4 * p + q] != 0.0:
                    _rotate(A, V, p, q)
    top = 0
    for i in range(1, 4):
        if A[5 * i] > A[5 * top]:
            top = i
    w, x, y, z = V[12 + top], V[top], V[4 + top], V[8 + top]
    norm = sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    out = np.empty(4)
    cdef double[::1] o = out
    if w < 0.0:
        o[0], o[1], o[2], o[3] = -w, -x, -y, -z
    else:
        o[0], o[1], o[2], o[3] = w, x, y, z
    return out


def dcm_from_quat_one(const double[::1] q):
    """C (3, 3) of one unit quaternion [w, x, y, z]: conventions.dcm_from_quat's formula, the same bits."""
    cdef double w = q[0], x = q[1], y = q[2], z = q[3]
    cdef double xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z
    cdef double wx = w * x, wy = w * y, wz = w * z
    out = np.empty((3, 3))
    cdef double[:, ::1] C = out
    C[0, 0], C[0, 1], C[0, 2] = 1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)
    C[1, 0], C[1, 1], C[1, 2] = 2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)
    C[2, 0], C[2, 1], C[2, 2] = 2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)
    return out
