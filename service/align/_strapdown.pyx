# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The inertial-frame strapdown integration compiled (built at install; docs/performance.md, strapdown.py).

One pass over a chunk of whole blocks does what the block-wise numpy form of the algorithm does (coning and
sculling terms, a Hillis-Steele prefix product of each block's rotations, the chain of block starts, the
normalisation, the rotation of Δv into b0, the running sums), operation for operation in numpy's order, with the C
library's sin, cos and sqrt that numpy calls for float64, and no fused multiply-adds (-ffp-contract=off): the same
bits (tests/unit/test_strapdown.py keeps the numpy form as the oracle). Each element of a prefix product depends on
its block's earlier samples only, so a block's first n samples integrate to the same bits alone as within the
whole block: what the live path's records of an incomplete block rely on.

Frames and units: Δθ (rad) and Δv (m/s) in body axes; the attitude C_b^b0 as [w, x, y, z] with w ≥ 0; α (m/s) in
b0 axes.
"""
from cpython.buffer cimport PyBUF_SIMPLE, PyBuffer_Release, PyObject_GetBuffer
from libc.math cimport cos, sin, sqrt

include "_quaternion.pxi"

import numpy as np


cdef inline void _from_rotvec(const double* phi, double* q) noexcept nogil:
    """conventions.quat_from_rotvec: exp(φ/2), sin(x)/x by its series below 1e-4 rad."""
    cdef double half = 0.5 * sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]), k
    if half < 1e-4:
        k = 0.5 * (1.0 - half * half / 6.0)
    else:
        k = 0.5 * sin(half) / half
    q[0] = cos(half)
    q[1], q[2], q[3] = k * phi[0], k * phi[1], k * phi[2]


cdef void _scan(double* P, Py_ssize_t n) noexcept nogil:
    """P_k ← P_0 ⊗ … ⊗ P_k over n quaternions in place, by the Hillis-Steele scan: P[s:] = P[:-s] ⊗ P[s:] for
    s = 1, 2, 4 …, each pass from the top down so every right-hand side is the previous pass's (numpy's order)."""
    cdef Py_ssize_t step = 1, k
    while step < n:
        k = n - 1
        while k >= step:
            _quat_product(P + 4 * (k - step), P + 4 * k, P + 4 * k)
            k -= 1
        step *= 2


cdef void _integrate(double* q_b_b0, double* alpha_b0, double* dtheta_prev, double* dv_prev,
                     const double* dtheta, const double* dv, long row, long n, long M, double* q,
                     double* alpha) noexcept nogil:
    """The chunk's n samples (n a multiple of M; Δθ and Δv ``row`` doubles from one sample to the next) into q (n, 4)
    and α (n, 3), the state arrays updated in place.
    Block by block: the block's rotations and body-frame Δv, their prefix product chained to the block's start, then
    Δv rotated by the attitude at each sample's start and summed from the block's start."""
    cdef long block, start, k, i
    cdef double cr[3]
    cdef double cr2[3]
    cdef double rotated[3]
    cdef double turned[3]
    cdef double phi[3]
    cdef double within[3]
    cdef double first[4]
    cdef double* P
    cdef double* body
    cdef const double* th_prev
    cdef const double* v_prev
    cdef const double* th
    cdef const double* v
    cdef const double* q_at_start
    for block in range(n // M):
        start = block * M
        for i in range(4):
            first[i] = q_b_b0[i]
        P = q + 4 * start
        for k in range(start, start + M):
            th, v = dtheta + row * k, dv + row * k
            th_prev = dtheta + row * (k - 1) if k > 0 else dtheta_prev
            v_prev = dv + row * (k - 1) if k > 0 else dv_prev
            _cross(th_prev, th, cr)
            for i in range(3):
                phi[i] = th[i] + cr[i] / 12.0
            _from_rotvec(phi, q + 4 * k)
            # Δv + ½ Δθ×Δv + ⅙ Δθ×(Δθ×Δv) + (1/12)(Δθ_prev×Δv + Δv_prev×Δθ), held in α's row until it is summed
            _cross(th, v, rotated)
            _cross(th, rotated, turned)
            _cross(th_prev, v, cr)
            _cross(v_prev, th, cr2)
            body = alpha + 3 * k
            for i in range(3):
                body[i] = v[i] + 0.5 * rotated[i] + turned[i] / 6.0 + (cr[i] + cr2[i]) / 12.0
        _scan(P, M)
        for k in range(start, start + M):
            _quat_product(first, q + 4 * k, q + 4 * k)
            _normalize(q + 4 * k)
        # α: the block's own running sum of C(q at the sample's start) Δv_body (quat_rotate: v + w t + u × t with
        # t = 2 u × v), then the block's start added to it
        for k in range(start, start + M):
            q_at_start = q + 4 * (k - 1) if k > start else &first[0]
            body = alpha + 3 * k
            _cross(q_at_start + 1, body, rotated)
            for i in range(3):
                rotated[i] = 2.0 * rotated[i]
            _cross(q_at_start + 1, rotated, turned)
            for i in range(3):
                turned[i] = body[i] + q_at_start[0] * rotated[i] + turned[i]
                within[i] = turned[i] if k == start else within[i] + turned[i]
                body[i] = alpha_b0[i] + within[i]
        for i in range(4):
            q_b_b0[i] = q[4 * (start + M - 1) + i]
        for i in range(3):
            alpha_b0[i] = alpha[3 * (start + M - 1) + i]
    for i in range(3):
        dtheta_prev[i] = dtheta[row * (n - 1) + i]
        dv_prev[i] = dv[row * (n - 1) + i]


def integrate(double[::1] q_b_b0, double[::1] alpha_b0, double[::1] dtheta_prev, double[::1] dv_prev,
              const double[:, :] dtheta, const double[:, :] dv, long block_samples):
    """N samples (Δθ, Δv (N, 3), N a multiple of ``block_samples``; each row contiguous, the rows of both one stride
    apart: columns of the pipeline's sample rows, or arrays of their own) from the state (C_b^b0 (4,), α (3,), the
    previous Δθ and Δv (3,)), which is updated in place; returns C_b^b0 (N, 4) and α (N, 3) at the samples' ends."""
    cdef long n = dtheta.shape[0]
    if dv.shape[0] != n or dtheta.shape[1] != 3 or dv.shape[1] != 3 or n == 0 or block_samples < 1 \
            or n % block_samples:
        raise ValueError(f"{n} samples (3 columns each) are not whole blocks of {block_samples}")
    if dtheta.strides[1] != sizeof(double) or dv.strides[1] != sizeof(double) or dtheta.strides[0] != dv.strides[0] \
            or dtheta.strides[0] % sizeof(double):
        raise ValueError("integrate: Δθ and Δv rows contiguous, one stride apart")
    q_out = np.empty((n, 4))
    alpha_out = np.empty((n, 3))
    cdef double[:, ::1] q = q_out
    cdef double[:, ::1] alpha = alpha_out
    cdef long row = dtheta.strides[0] // sizeof(double)
    with nogil:
        _integrate(&q_b_b0[0], &alpha_b0[0], &dtheta_prev[0], &dv_prev[0], &dtheta[0, 0], &dv[0, 0], row, n,
                   block_samples, &q[0, 0], &alpha[0, 0])
    return q_out, alpha_out


def rows_offset(object owner, const double[:] t, const double[:, :] dtheta, const double[:, :] dv):
    """Where the rows (t, Δθ, Δv) whose columns are ``t`` (N,), ``dtheta`` and ``dv`` (N, 3) lie in ``owner``'s
    buffer (their base: a log reader's block), in bytes from its start: -1 unless each row is seven float64 in
    order, 56 bytes after the last, all inside one contiguous buffer. Addresses compared, nothing read: the pipeline
    reads such rows in place (``numpy.ndarray(..., buffer=owner, offset=...)``) without the array-interface dicts,
    whose keys Python interns anew at every call."""
    cdef Py_ssize_t n = t.shape[0], row = 7 * sizeof(double), offset
    cdef Py_buffer view
    if (n == 0 or dtheta.shape[0] != n or dv.shape[0] != n or dtheta.shape[1] != 3 or dv.shape[1] != 3
            or t.strides[0] != row or dtheta.strides[0] != row or dv.strides[0] != row
            or dtheta.strides[1] != sizeof(double) or dv.strides[1] != sizeof(double)
            or <const char*>&dtheta[0, 0] != <const char*>&t[0] + sizeof(double)
            or <const char*>&dv[0, 0] != <const char*>&t[0] + 4 * sizeof(double)):
        return -1
    try:
        PyObject_GetBuffer(owner, &view, PyBUF_SIMPLE)
    except BufferError:   # not one contiguous buffer
        return -1
    offset = <const char*>&t[0] - <const char*>view.buf
    if offset < 0 or offset + n * row > view.len:
        offset = -1
    PyBuffer_Release(&view)
    return offset


def prefix_product(double[:, :, ::1] P):
    """In place, along the middle axis of P (B, N, 4): P_k ← P_0 ⊗ … ⊗ P_k, by the Hillis-Steele scan in numpy's
    order (each pass takes the previous pass's elements: run from the end, an element's partner is not yet
    overwritten), the same bits as ``strapdown.prefix_quat_product``'s numpy form."""
    cdef Py_ssize_t b
    if P.shape[2] != 4:
        raise ValueError("prefix_product: quaternions of 4 components along the last axis")
    for b in range(P.shape[0]):
        _scan(&P[b, 0, 0], P.shape[1])
