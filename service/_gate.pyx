# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The sample gate's per-row screens compiled (built at install; sample_gate.py, docs/performance.md): one pass over
a call's rows instead of a dozen numpy calls, which on the live path's one or few samples cost more than the
arithmetic. Each screen is the numpy expression named in its docstring, NaN included."""
from libc.math cimport INFINITY, fabs, isnan, rint

import numpy as np

from sinsalign.protocol.buffers import read_sized


cdef inline double _abs_max3(double a, double b, double c) noexcept nogil:
    """numpy's max of |a|, |b|, |c|: NaN if any is."""
    cdef double m = fabs(a), v
    for v in (fabs(b), fabs(c)):
        if v > m or isnan(v):
            m = v
    return m


def screen(const double[:, :] rows, const long[:] saturated, double max_dtheta_rad, double max_dv_mps,
           double max_time_s):
    """Rows (N, ≥ 7: t s, Δθ rad, Δv m/s) and their saturated flags (N,) → (largest |Δθ| (N,), largest |Δv| (N,),
    clockless: not |t| ≤ ``max_time_s``, out of range: an increment beyond the IMU's range in a row not flagged
    saturated, refused: any of the three)."""
    cdef long n = rows.shape[0], k
    dtheta_out, dv_out = read_sized(n), read_sized(n)
    clockless_out, range_out, refused_out = (read_sized(n, dtype=np.bool_) for _ in range(3))
    cdef double[::1] dtheta_max = dtheta_out, dv_max = dv_out
    cdef unsigned char[::1] clockless = clockless_out.view(np.uint8), beyond = range_out.view(np.uint8)
    cdef unsigned char[::1] refused = refused_out.view(np.uint8)
    for k in range(n):
        dtheta_max[k] = _abs_max3(rows[k, 1], rows[k, 2], rows[k, 3])
        dv_max[k] = _abs_max3(rows[k, 4], rows[k, 5], rows[k, 6])
        clockless[k] = not (fabs(rows[k, 0]) <= max_time_s)
        beyond[k] = (dtheta_max[k] > max_dtheta_rad or dv_max[k] > max_dv_mps) and saturated[k] == 0
        refused[k] = clockless[k] or beyond[k] or saturated[k] != 0
    return dtheta_out, dv_out, clockless_out, range_out, refused_out


def plain_rows(const double[:] t, const unsigned char[:] refused, double last_t, double period_s):
    """Whether each row follows the one before it (``last_t`` for the first; NaN: none) as a plain sample: not
    refused, later, and not after a gap (round((t − before) / period) − 1 not above 0, numpy's round half to
    even)."""
    cdef long n = t.shape[0], k
    cdef double before
    out = read_sized(n, dtype=np.bool_)
    cdef unsigned char[::1] plain = out.view(np.uint8)
    for k in range(n):
        before = (-INFINITY if isnan(last_t) else last_t) if k == 0 else t[k - 1]
        plain[k] = not refused[k] and t[k] > before and not (rint((t[k] - before) / period_s) - 1.0 > 0.0)
    if n and isnan(last_t):
        plain[0] = not refused[0]
    return out
