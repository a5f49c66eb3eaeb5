# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""One attitude's conversions compiled (built at install; docs/performance.md): the quaternion of a K matrix's top
eigenvector and the DCM of one quaternion, each called once per control step or record.

The top eigenvector comes from cyclic Jacobi rotations of the symmetric 4×4 K (_linalg.pxi), run until the
off-diagonal is zero in floating point: each rotation is orthogonal to the last bit, so the eigenvector is as
accurate as LAPACK's (which ``numpy.linalg.eigh`` calls) and differs from it by rounding divided by the gap between
K's two largest eigenvalues (tests/unit/test_attitude_kernels.py). The DCM is conventions.dcm_from_quat's formula element by element,
the same bits (compiled with -ffp-contract=off: no fused multiply-adds).

Quaternions are Hamilton [w, x, y, z] with w ≥ 0, as conventions.quat_normalize gives them.
"""
from libc.math cimport fabs, sqrt

include "_linalg.pxi"

import numpy as np


def quaternion_from_K(const double[:, :] K):
    """[w, x, y, z] (w ≥ 0) of the eigenvector of the symmetric K (4, 4) with the largest eigenvalue, K's rows
    ordered (x, y, z, w) as solvers.quaternion_from_K takes them."""
    cdef double A[16]
    cdef double V[16]
    cdef double w, x, y, z, norm
    cdef int i, j, top
    for i in range(4):
        for j in range(4):
            A[4 * i + j] = 0.5 * (K[i, j] + K[j, i])
    jacobi_eigen(4, A, V)
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
