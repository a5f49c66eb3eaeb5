# The fixed base's policy rules that both the compiled block loop (_blocks.pyx) and the Python steps take: written
# once, here, and called from Python through the wrappers of _blocks.pyx and _compass.pyx.
#
# Units: time s, σ deg where named so, else rad.

cdef double _geometric(const double* knots, const double* values, int n, double t) noexcept nogil:
    """The gain schedule's σ at loop time ``t`` (compass.GainSchedule): between ``knots`` (n, increasing from 0)
    interpolated geometrically, so the gains change smoothly; a value of 0 stays 0 until its knot (a loop not yet
    on); after the last knot its value."""
    cdef int j = 0
    cdef double a, b, f
    if t >= knots[n - 1]:
        return values[n - 1]
    while j + 1 < n and knots[j + 1] <= t:   # bisect_right − 1
        j += 1
    a, b = values[j], values[j + 1]
    if a <= 0.0:
        return 0.0 if b <= 0.0 or t < knots[j + 1] else b
    f = (t - knots[j]) / (knots[j + 1] - knots[j])
    return a * pow(b / a, f)


cdef void _level_gains(double sigma, double gravity, double radius_m, double* K) noexcept nogil:
    """(K1, K2, K3) of the third-order level loop with poles −σ, −σ ± jσ (σ rad/s; Schuler ω_s² = g / R)."""
    K[0] = 3.0 * sigma
    K[1] = 4.0 * pow(sigma, 2.0) / (gravity / radius_m) - 1.0
    K[2] = 2.0 * pow(sigma, 3.0) / gravity


cdef void _azimuth_gains(double sigma, double gravity, double radius_m, double* K) noexcept nogil:
    """(K1, K2, K3, K4) of the fourth-order azimuth loop with double poles −σ ± jσ (σ rad/s)."""
    K[0] = 2.0 * sigma
    K[1] = 4.0 * pow(sigma, 2.0) / (gravity / radius_m) - 1.0
    K[2] = 2.0 * sigma
    K[3] = 4.0 * pow(sigma, 4.0) / gravity


cdef void _process_noise(double vrw2, double arw2, double dt_s, double* Q) noexcept nogil:
    """The compass loops' process noise of one step of ``dt_s`` s into the diagonal of Q (8 × 8, row-major, its other
    entries left as they are): the velocity random walk² (m²/s³) on the two velocities, the angle random walk²
    (rad²/s) on the three platform angles (compass.py's state order: VE, VN, PE, PN, PU, IE, IN, YU)."""
    Q[0] = Q[9] = vrw2 * dt_s
    Q[18] = Q[27] = Q[36] = arw2 * dt_s


cdef double _noise_part(double sigma_deg, double bias_rad, double efficiency) noexcept nogil:
    """The noise part (rad) of a coarse σ (deg): the bias limit ``bias_rad`` taken out and the estimator's efficiency
    factor divided out (sensor_model.ESTIMATOR_EFFICIENCY): what seeds the compass loops and what the hand-over
    judges."""
    cdef double rad = sigma_deg * (M_PI / 180.0)
    return sqrt(max(rad * rad - bias_rad * bias_rad, 0.0) / efficiency)


cdef enum:
    COARSE_TERMS = 9   # the coarse σ model's terms of a grade and site (sensor_model._SigmaTerms.kernel)


cdef void _coarse_variances(const double* terms, double efficiency, double T, double* heading2,
                            double* level2) noexcept nogil:
    """The coarse stage's σ model (sensor_model.inertial_alignment_sigma), heading² and level² in rad² after T > 0 s:
    the bias limit, the gyro bias's drift ε T, and the noise of a least-squares fit of the α history scaled by the
    estimator's efficiency. ``terms``: the accelerometer's white noise in heading over T³, the gyro's walk over T, a
    bounded disturbance over T⁵ (rad² sᵏ), the heading bias limit² (rad²), the gyro bias (rad/s), the level bias
    limit² (rad²), and in level the accelerometer's noise over T, the walk times T and the disturbance over T³."""
    cdef double drift2 = pow(terms[4] * T, 2.0)
    heading2[0] = terms[3] + drift2 + efficiency * (terms[0] / pow(T, 3.0) + terms[1] / T + terms[2] / pow(T, 5.0))
    level2[0] = terms[5] + drift2 + efficiency * (terms[6] / T + terms[7] * T + terms[8] / pow(T, 3.0))


cdef bint _handover_due(bint by_time, double time_s, double least_s, double sigma_deg, double unknown_deg,
                        double efficiency, double elapsed_s, long n_obs, const double* terms) noexcept nogil:
    """Whether the coarse stage hands over to the compass loops after ``elapsed_s``: at the configured ``time_s``
    (``by_time``), or from ``least_s`` on once the noise part of the coarse heading σ is within ``sigma_deg``.
    ``terms`` (FixedBase.handover_terms): the coarse σ model's :data:`COARSE_TERMS` of the grade σ takes, then the
    datasheet's heading bias limit (rad), and 1 while the data's noise has not checked σ. A heading at the unknown
    angle's σ (``unknown_deg``) has no noise part to hand over."""
    cdef double heading2, level2, heading_deg
    if by_time:
        return elapsed_s >= time_s
    if n_obs == 0 or elapsed_s < least_s or terms[COARSE_TERMS + 1] != 0.0 or elapsed_s <= 0.0:
        return False
    _coarse_variances(terms, efficiency, elapsed_s, &heading2, &level2)
    heading_deg = min(sqrt(heading2) / (M_PI / 180.0), unknown_deg)
    if heading_deg >= unknown_deg:
        return False
    return _noise_part(heading_deg, terms[COARSE_TERMS], efficiency) / (M_PI / 180.0) <= sigma_deg
