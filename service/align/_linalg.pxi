# Small dense linear algebra shared by the compiled kernels: included (include "_linalg.pxi") into each module that
# uses it, so each compiles its own copy and no module imports another at run time. The including module cimports
# fabs and sqrt from libc.math. Matrices are row-major C arrays of doubles; n ≤ 8.
cdef enum:
    MAX_SWEEPS = 60   # a 4×4 takes 5-6 sweeps


cdef inline void _jacobi_rotate(int n, double* A, double* V, int p, int q) noexcept nogil:
    """One Jacobi rotation of the n×n symmetric A that zeroes A[p, q]; V accumulates it."""
    cdef double apq = A[n * p + q], theta, t, c, s, akp, akq
    cdef int k
    theta = (A[n * q + q] - A[n * p + p]) / (2.0 * apq)
    if fabs(theta) > 1e150:   # θ² would overflow: t = 1 / (2θ) to first order
        t = 0.5 / theta
    else:
        t = 1.0 / (fabs(theta) + sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / sqrt(t * t + 1.0)
    s = t * c
    for k in range(n):
        akp, akq = A[n * k + p], A[n * k + q]
        A[n * k + p] = c * akp - s * akq
        A[n * k + q] = s * akp + c * akq
    for k in range(n):
        akp, akq = A[n * p + k], A[n * q + k]
        A[n * p + k] = c * akp - s * akq
        A[n * q + k] = s * akp + c * akq
    A[n * p + q] = A[n * q + p] = 0.0
    for k in range(n):
        akp, akq = V[n * k + p], V[n * k + q]
        V[n * k + p] = c * akp - s * akq
        V[n * k + q] = s * akp + c * akq


cdef inline void jacobi_eigen(int n, double* A, double* V) noexcept nogil:
    """Eigen-decomposition of the symmetric n×n A by cyclic Jacobi rotations, run until the off-diagonal is zero in
    floating point: A ends diagonal (the eigenvalues), V (set here) holds the eigenvectors as its columns. Each
    rotation is orthogonal to the last bit, so the eigenvectors are as accurate as LAPACK's."""
    cdef double off, scale, apq
    cdef int i, j, p, q, sweep
    for i in range(n):
        for j in range(n):
            V[n * i + j] = 1.0 if i == j else 0.0
    for sweep in range(MAX_SWEEPS):
        off = 0.0
        scale = 0.0
        for p in range(n):
            scale += fabs(A[(n + 1) * p])
            for q in range(p + 1, n):
                off += fabs(A[n * p + q])
        if off == 0.0 or off <= 1e-300 * scale:
            return
        for p in range(n):
            for q in range(p + 1, n):
                apq = fabs(A[n * p + q])
                # an element below the last place of both diagonal terms is zero already: set it so
                if fabs(A[(n + 1) * p]) + 1e3 * apq == fabs(A[(n + 1) * p]) and \
                        fabs(A[(n + 1) * q]) + 1e3 * apq == fabs(A[(n + 1) * q]):
                    A[n * p + q] = A[n * q + p] = 0.0
                elif apq != 0.0:
                    _jacobi_rotate(n, A, V, p, q)


cdef void _top_quaternion(const double* K, double* q) noexcept nogil:
    """q = [w, x, y, z] (w ≥ 0) of the eigenvector of the symmetric K (16, row-major; rows ordered (x, y, z, w) as
    solvers.quaternion_from_K takes them) with the largest eigenvalue: cyclic Jacobi rotations of (K + Kᵀ) / 2."""
    cdef double A[16]
    cdef double V[16]
    cdef double w, x, y, z, norm
    cdef int i, j, top
    for i in range(4):
        for j in range(4):
            A[4 * i + j] = 0.5 * (K[4 * i + j] + K[4 * j + i])
    jacobi_eigen(4, A, V)
    top = 0
    for i in range(1, 4):
        if A[5 * i] > A[5 * top]:
            top = i
    w, x, y, z = V[12 + top], V[top], V[4 + top], V[8 + top]
    norm = sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    if w < 0.0:
        q[0], q[1], q[2], q[3] = -w, -x, -y, -z
    else:
        q[0], q[1], q[2], q[3] = w, x, y, z
