# OPREQ's (REQUEST's, the q-method's) fold shared by the compiled kernels: included (include "_fold.pxi") into each
# module that uses it. solvers.RecursiveK.fold describes it.


cdef void _fold(double* k, const double* dK, const double* trace_R, Py_ssize_t count, double* m, double* trace_P,
                long* n, double* rho, double trace_Q, int policy, double fixed_rho) noexcept nogil:
    """K (16, row-major) ← a K + c δK for each of ``count`` prepared observations (δK (count, 16), tr R (count,)) in
    order, with the gain of ``policy`` (0 OPREQ's ρ*, 1 REQUEST's fixed ρ, 2 the q-method's 1/(n + 1)); the
    scalars m, tr P, n and ρ advanced in place, in Python's order."""
    cdef Py_ssize_t j, i
    cdef double m_new, a, c, tr_R
    cdef const double* d
    for j in range(count):
        tr_R = trace_R[j]
        d = dK + 16 * j
        if n[0] == 0:   # K_0 = δK_0, P_0 = R_0, m_0 = 1
            for i in range(16):
                k[i] = d[i]
            m[0], trace_P[0], rho[0] = 1.0, tr_R, 1.0
        else:
            trace_P[0] = trace_P[0] + trace_Q
            if policy == 0:
                rho[0] = m[0] * m[0] * trace_P[0] / (m[0] * m[0] * trace_P[0] + tr_R)
            elif policy == 1:
                rho[0] = fixed_rho
            else:
                rho[0] = 1.0 / (<double>n[0] + 1.0)
            m_new = (1.0 - rho[0]) * m[0] + rho[0]
            a = (1.0 - rho[0]) * m[0] / m_new
            c = rho[0] / m_new
            trace_P[0] = a * a * trace_P[0] + c * c * tr_R
            for i in range(16):
                k[i] = a * k[i] + c * d[i]
            m[0] = m_new
        n[0] += 1
