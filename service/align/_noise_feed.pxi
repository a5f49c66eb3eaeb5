# The noise meter's per-observation loop shared by the compiled kernels: included (include "_noise_feed.pxi") after
# _fixed_site.pxi into each module that uses it. noise_check.NoiseMeter.feed describes it; the including module cimports
# sqrt from libc.math. Units: elapsed s, α and β m/s, b0 and n0 axes; arrays row-major.


cdef inline long _pymod(long a, long n) noexcept nogil:
    cdef long r = a % n
    return r + n if r < 0 else r


cdef long _hadamard_feed(double lat, double gravity, const double* elapsed_s, const double* alpha_b0, long count,
                         double* alpha_sum, double* beta_sum, long capacity, double* moments, const long* lags,
                         long n_lags, double* sums, double* counts, const double* C, long* steps, long* bad_until,
                         long settle_steps, double outlier_factor, long min_outlier_count, long verdict_steps,
                         bint* verdict_due) noexcept nogil:
    """The meter's rings and sums updated in place by ``count`` observations (elapsed (count,), α (count, 3)), with
    the rough C_n0^b0 (9) or NULL; ``moments`` (:data:`noise_check.MOMENTS`): Σ α, Σ β (their running sums, the
    rings' newest entries), Σ t α, Σ t β, Σ t² α, Σ t² β (3 each), then Σ tᵏ for k = 0..4; ``steps`` and ``bad_until`` advanced, ``verdict_due`` set when a step count that
    is a multiple of ``verdict_steps`` is reached; returns the outliers found."""
    cdef long m, k, j, i, r, slot, lag
    cdef double stencil[5]
    stencil[:] = [1.0, -4.0, 6.0, -4.0, 1.0]
    cdef double beta[3]
    cdef double d[3]
    cdef double e[3]
    cdef double up[3]
    cdef double norm, dd, du, square, t
    cdef const double* a
    cdef long outliers = 0
    for m in range(count):
        k = steps[0]
        a = alpha_b0 + 3 * m
        _beta_fixed(lat, gravity, elapsed_s[m], beta)
        slot = k % capacity
        t = elapsed_s[m]
        for i in range(3):
            moments[i] += a[i]
            moments[3 + i] += beta[i]
            moments[6 + i] += t * a[i]
            moments[9 + i] += t * beta[i]
            moments[12 + i] += t * t * a[i]
            moments[15 + i] += t * t * beta[i]
            alpha_sum[3 * slot + i] = moments[i]
            beta_sum[3 * slot + i] = moments[3 + i]
        moments[18] += 1.0
        moments[19] += t
        moments[20] += t * t
        moments[21] += t * t * t
        moments[22] += t * t * t * t
        steps[0] += 1
        verdict_due[0] = verdict_due[0] or steps[0] % verdict_steps == 0
        if k < 4 * lags[0]:
            continue
        norm = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
        for i in range(3):
            up[i] = a[i] / norm
        for j in range(n_lags):
            lag = lags[j]
            if k < 4 * lag:
                break   # longer lags are not ready either
            for i in range(3):
                d[i] = 0.0
                e[i] = 0.0
            for r in range(5):
                slot = _pymod(k - r * lag, capacity)
                for i in range(3):
                    d[i] += stencil[r] * alpha_sum[3 * slot + i]
                    e[i] += stencil[r] * beta_sum[3 * slot + i]
            if C != NULL:
                for i in range(3):
                    d[i] = d[i] - (e[0] * C[3 * i] + e[1] * C[3 * i + 1] + e[2] * C[3 * i + 2])
            dd = 0.0
            du = 0.0
            for i in range(3):
                d[i] = d[i] / lag
                dd += d[i] * d[i]
                du += d[i] * up[i]
            square = 0.5 * (dd - du * du)
            if j == 0 and counts[0] >= min_outlier_count and square > outlier_factor * sums[0] / counts[0]:
                outliers += 1
                bad_until[0] = k + settle_steps
            if k - 4 * lag > bad_until[0]:
                sums[j] += square
                counts[j] += 1
    return outliers
