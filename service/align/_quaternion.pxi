# One quaternion's and one vector's arithmetic shared by the compiled kernels: included (include "_quaternion.pxi")
# into each module that uses it, as _linalg.pxi is. Each function is the conventions.py form's arithmetic in its
# order (no fused multiply-adds: the modules compile with -ffp-contract=off), so it gives numpy's bits. The
# including module cimports sqrt from libc.math. Quaternions are Hamilton [w, x, y, z]; matrices row-major 9.


cdef inline void _cross(const double* a, const double* b, double* out) noexcept nogil:
    """a × b: conventions.cross."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


cdef inline void _quat_product(const double* p, const double* q, double* out) noexcept nogil:
    """p ⊗ q: conventions.quat_multiply; ``out`` may be ``p`` or ``q``."""
    cdef double w = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    cdef double x = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    cdef double y = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    cdef double z = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]
    out[0], out[1], out[2], out[3] = w, x, y, z


cdef inline void _normalize(double* q) noexcept nogil:
    """q / |q| in place, then the sign with w ≥ 0: conventions.quat_normalize."""
    cdef double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    cdef int i
    for i in range(4):
        q[i] = q[i] / norm
    if q[0] < 0.0:
        for i in range(4):
            q[i] = -q[i]


cdef inline void _dcm(double w, double x, double y, double z, double* C) noexcept nogil:
    """C of the unit quaternion [w, x, y, z]: conventions.dcm_from_quat."""
    cdef double xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z
    cdef double wx = w * x, wy = w * y, wz = w * z
    C[0], C[1], C[2] = 1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)
    C[3], C[4], C[5] = 2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)
    C[6], C[7], C[8] = 2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)
