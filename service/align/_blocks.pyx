# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The fixed-base pipeline's control steps over a chunk, compiled (built at install; docs/performance.md).

Between two output epochs a fixed-base block does the same five things: fold the block's observations into K, feed
them to the noise meter, take the compass loops' step with the gains of the schedule, check the base for motion
under K's attitude, and move on. :class:`FixedBaseBlocks` runs that sequence for a run of blocks in one C loop, with
the same functions the single kernels wrap (the .pxi files), in the order ``AlignmentPipeline`` calls them: the
same bits. It hands the block back to the pipeline's Python steps wherever they decide something (:meth:`run`
returns which): a noise verdict due, the hand-over to the loops, the step that fills the loops' store (the
stored-data passes start), a velocity that calls for the estimate's σ (a quarter of the motion threshold); the
pipeline calls it only while nothing else is pending (no epoch, no passes under way, no motion episode: the
pipeline's own readiness test).

Units and frames as in the modules it stands in for: time s, α and β m/s (b0, n0 axes), rates rad/s, matrices
row-major.
"""
from libc.math cimport M_PI, ceil, cos, fabs, log2, pow, sin, sqrt

include "_linalg.pxi"
include "_quaternion.pxi"
include "_fixed_site.pxi"
include "_noise_feed.pxi"
include "_fold.pxi"
include "_platform.pxi"
include "_compass_core.pxi"
include "_policy.pxi"

import numpy as np

cdef enum:   # where :meth:`FixedBaseBlocks.run` stopped (the names below)
    STOP_DONE, STOP_VERDICT, STOP_CONTROL, STOP_MOTION

DONE = STOP_DONE
"""Every block up to the limit run."""
VERDICT = STOP_VERDICT
"""The block's observations folded and fed to the noise meter, whose verdict is due: the verdict and the block's
control step are left (:meth:`FixedBaseBlocks.run` with ``resume`` takes the step)."""
CONTROL = STOP_CONTROL
"""The block's observations folded and measured; its control step is the Python steps': the hand-over to the loops,
or the step that fills their store (the passes start)."""
MOTION = STOP_MOTION
"""The block's control step taken but for the motion check, which needs the estimate's σ."""

cdef enum:
    F_SLOTS = 8   # transition matrices kept: the steps' few lengths at the final gains
    KEY = 10      # level K1..K3, azimuth on, azimuth K1..K4, Earth-rate sign, step length
    MAX_KNOTS = 32



cdef class FixedBaseBlocks:
    """The constants of one pipeline's estimators and the loops' recent transition matrices; :meth:`run` takes the
    estimators' state from their objects and writes it back."""

    cdef double lat, gravity
    # the solver's gain policy
    cdef double trace_Q, fixed_rho
    cdef int policy
    # the noise meter
    cdef bint with_noise
    cdef long settle_steps, min_outlier_count, verdict_steps
    cdef double outlier_factor
    # the motion monitor
    cdef bint with_motion
    cdef long ring_n
    cdef double suspect_mps, suspect_mps_per_s, check_interval_s
    # the compass loops
    cdef bint with_fine
    cdef int n_knots
    cdef double knots[MAX_KNOTS]
    cdef double level_sigma[MAX_KNOTS]
    cdef double azimuth_sigma[MAX_KNOTS]
    cdef double radius_m, omega_cos, omega_sin, loops_gravity
    cdef double omega_ie_n[3]
    cdef int handover   # 0 by σ, 1 at a time
    cdef double handover_time_s, handover_min_s, handover_sigma_deg, sigma_unknown_deg, efficiency
    # the estimators' arrays, for their life (a restart builds new ones and a new loop), and the chunk's
    cdef double[:, ::1] alpha_sum, beta_sum, ring_alpha, ring_beta, stored_dalpha
    cdef double[::1] moments
    cdef const long[::1] lags
    cdef double[::1] sums, counts, ring_elapsed, stored_dt
    cdef double[:, :, ::1] ring_C
    cdef const Py_ssize_t[::1] ends, fold_end
    cdef const double[:] t, elapsed
    cdef const double[:, :] alpha
    cdef object alpha_array
    cdef const double[:, :, ::1] dK
    cdef const double[::1] trace_R, observed_s
    cdef const double[:, ::1] observed_alpha
    cdef object solver, noise, motion, fine   # the estimators whose state a run takes and gives back
    cdef double keys[F_SLOTS][KEY]
    cdef double F[F_SLOTS][64]
    cdef int n_F, next_F

    def __init__(self, double lat, double gravity, solver, int policy, noise, noise_constants, motion,
                 double suspect_mps, double suspect_mps_per_s, double check_interval_s, fine, handover,
                 double sigma_unknown_deg, double efficiency):
        """``solver``: the RecursiveK and its gain ``policy`` (solvers._GAIN_POLICY); ``noise``: the NoiseMeter or
        None, with ``noise_constants`` (settle steps, outlier factor, least outlier count, verdict steps);
        ``motion``: the MotionMonitor or None, checked every ``check_interval_s``, a window's velocity above
        ``suspect_mps`` + ``suspect_mps_per_s`` × the alignment's time asking for σ (disturbance.SUSPECT_FRACTION of
        its threshold, which grows with the gyros' drift); ``fine``: the FineAlignment or
        None (its loops' schedule and site constants), with the compass configuration's ``handover`` (its kind, time,
        least time and σ), σ's ceiling ``sigma_unknown_deg`` and the estimator's ``efficiency``
        (sensor_model.ESTIMATOR_EFFICIENCY)."""
        cdef int i
        self.solver, self.noise, self.motion, self.fine = solver, noise, motion, fine
        self.lat, self.gravity = lat, gravity
        self.trace_Q, self.fixed_rho, self.policy = solver.trace_Q, solver.fixed_rho, policy
        self.with_noise = noise is not None
        if self.with_noise:
            self.settle_steps, self.outlier_factor, self.min_outlier_count, self.verdict_steps = noise_constants
            (self.alpha_sum, self.beta_sum, self.moments, self.lags, self.sums,
             self.counts) = noise.running_sums
        self.with_motion = motion is not None
        if self.with_motion:
            self.suspect_mps, self.suspect_mps_per_s = suspect_mps, suspect_mps_per_s
            self.check_interval_s = check_interval_s
            self.ring_n, self.ring_elapsed, self.ring_alpha, self.ring_beta, self.ring_C = motion.ring
        self.with_fine = fine is not None
        self.n_F = self.next_F = 0
        if self.with_fine:
            loops = fine.loops
            schedule = loops.schedule
            self.n_knots = len(schedule.time_s)
            if self.n_knots > MAX_KNOTS:
                raise ValueError(f"FixedBaseBlocks: at most {MAX_KNOTS} schedule knots")
            for i in range(self.n_knots):
                self.knots[i] = schedule.time_s[i]
                self.level_sigma[i] = schedule.level_sigma[i]
                self.azimuth_sigma[i] = schedule.azimuth_sigma[i]
            self.radius_m, self.loops_gravity = loops.radius_m, loops.gravity
            self.omega_cos, self.omega_sin = loops.omega_cos, loops.omega_sin
            for i in range(3):
                self.omega_ie_n[i] = loops.omega_ie_n[i]
            self.stored_dalpha, self.stored_dt = fine.buffer.dalpha, fine.buffer.dt_s
            self.handover = 1 if handover.handover == "time" else 0
            self.handover_time_s, self.handover_min_s = handover.handover_time_s, handover.handover_min_s
            self.handover_sigma_deg, self.sigma_unknown_deg = handover.handover_sigma_deg, sigma_unknown_deg
            self.efficiency = efficiency

    cdef const double* _transition_of(self, const double* key) noexcept nogil:
        """F of ``key`` (:data:`KEY` values), from the kept ones or computed (the oldest kept one replaced)."""
        cdef int s, i
        cdef bint same
        for s in range(self.n_F):
            same = True
            for i in range(KEY):
                if self.keys[s][i] != key[i]:
                    same = False
                    break
            if same:
                return self.F[s]
        s = self.next_F
        self.next_F = (self.next_F + 1) % F_SLOTS
        if self.n_F < F_SLOTS:
            self.n_F += 1
        for i in range(KEY):
            self.keys[s][i] = key[i]
        _transition(key[0], key[1], key[2], key[3] != 0.0, key[4], key[5], key[6], key[7], key[8],
                    self.loops_gravity, self.radius_m, self.omega_cos, self.omega_sin, key[9], self.F[s])
        return self.F[s]

    def chunk(self, const Py_ssize_t[::1] ends, const Py_ssize_t[::1] fold_end, const double[:] t,
              const double[:] elapsed, alpha_array, const double[:, :, ::1] dK, const double[::1] trace_R,
              const double[::1] observed_s, const double[:, ::1] observed_alpha) -> None:
        """The chunk :meth:`run` takes its blocks from: block c's samples end at ``ends[c]`` (times ``t`` s, elapsed
        since the start s, α (N, 3) m/s), its observations are folded up to ``fold_end[c]`` (δK, tr R, their times
        and α as the noise meter takes them)."""
        self.ends, self.fold_end, self.t, self.elapsed = ends, fold_end, t, elapsed
        self.alpha_array, self.alpha = alpha_array, alpha_array
        self.dK, self.trace_R, self.observed_s, self.observed_alpha = dK, trace_R, observed_s, observed_alpha

    def run(self, Py_ssize_t b, Py_ssize_t limit, Py_ssize_t folded, Py_ssize_t measured, bint resume, step_alpha,
            double step_t, double next_check, handover):
        """Blocks ``b`` to ``limit`` − 1 of the chunk (:meth:`chunk`), the first with its observations folded up to
        ``folded`` already and measured from ``measured`` on (``resume``: all of them folded and measured, its
        control step left). The pipeline's control-step state goes in and comes back: α (3,) m/s and the time (s) of
        the last control step, and the elapsed time (s) of the next motion check; ``handover``
        (:meth:`FixedBase.handover_terms`) where the loops have not started, else None. The estimators' own state is
        taken from them and given back through their faces (``RecursiveK.load``, the meter's and the monitor's
        counts, the loops' state). Returns (the block it stopped at, :data:`DONE`, :data:`VERDICT`, :data:`CONTROL`
        or :data:`MOTION`, the observations folded, the last control step's α and time, the next check's time)."""
        cdef const Py_ssize_t[::1] ends = self.ends, fold_end = self.fold_end
        cdef const double[:] t = self.t, elapsed = self.elapsed
        cdef const double[:, :] alpha = self.alpha
        cdef const double[:, :, ::1] dK = self.dK
        cdef const double[::1] trace_R = self.trace_R, observed_s = self.observed_s
        cdef const double[:, ::1] observed_alpha = self.observed_alpha
        cdef Py_ssize_t c = b, e, upto, i, j
        solver, noise, motion, fine = self.solver, self.noise, self.motion, self.fine
        # the solver
        K_out = np.array(solver.K, dtype=float, copy=True)
        cdef double[:, ::1] K_view = K_out
        cdef double* K = &K_view[0, 0]
        cdef double m = solver.m, trace_P = solver.trace_P, rho = solver.rho
        cdef long n_obs = solver.n_obs
        cdef double q[4]
        known = solver.known_quaternion
        cdef bint q_known = known is not None, q_new = False
        cdef const double[::1] q_view
        if q_known:
            q_view = known
            q[0], q[1], q[2], q[3] = q_view[0], q_view[1], q_view[2], q_view[3]
        # the pipeline's step
        cdef double alpha_step[3]
        cdef const double[:] alpha_step_view = step_alpha
        alpha_step[0], alpha_step[1], alpha_step[2] = alpha_step_view[0], alpha_step_view[1], alpha_step_view[2]
        cdef double t_step = step_t, next_check_s = next_check
        # the noise meter
        cdef double[:, ::1] alpha_sum, beta_sum
        cdef double[::1] moments
        cdef const long[::1] lags
        cdef double[::1] sums, counts
        cdef const double[:, :] C_rough_view
        cdef double C_rough[9]
        cdef bint with_rough = False
        cdef long steps = 0, bad_until = 0, outliers = 0
        cdef bint verdict_due = False
        if self.with_noise:
            alpha_sum, beta_sum, moments = self.alpha_sum, self.beta_sum, self.moments
            lags, sums, counts = self.lags, self.sums, self.counts
            steps, bad_until = noise.steps, noise.bad_until
            if noise.C_n0_b0 is not None:
                with_rough = True
                C_rough_view = noise.C_n0_b0
                for i in range(3):
                    for j in range(3):
                        C_rough[3 * i + j] = C_rough_view[i, j]
        # the motion monitor
        cdef double[::1] ring_elapsed
        cdef double[:, ::1] ring_alpha, ring_beta
        cdef double[:, :, ::1] ring_C
        cdef long ring_count = 0, slot, oldest
        cdef double window_speed = 0.0, speed = 0.0
        cdef bint checked = False
        if self.with_motion:
            ring_elapsed, ring_alpha, ring_beta = self.ring_elapsed, self.ring_alpha, self.ring_beta
            ring_C = self.ring_C
            ring_count = motion.ring_count
        # the compass loops
        cdef double[:, ::1] C_b0_p, P, stored_dalpha
        cdef double[::1] V, stored_dt
        cdef Py_ssize_t stored = 0, capacity = 0
        cdef bint passes_done = True, active = False
        cdef double handover_terms[COARSE_TERMS + 2]
        cdef double I_E = 0.0, I_N = 0.0, y = 0.0, t_loop_s = 0.0, earth_sign = 1.0, vrw2 = 0.0, arw2 = 0.0
        cdef bint azimuth_on = False
        if self.with_fine:
            state = fine.state
            active = state is not None
            if active:
                C_b0_p, V, P = state.C_b0_p, state.V, state.P
                I_E, I_N, y, t_loop_s = state.I_E, state.I_N, state.y, state.t_loop_s
                azimuth_on, earth_sign = state.azimuth_on, state.earth_sign
            else:
                for i, term in enumerate(handover):
                    handover_terms[i] = term
            grade = fine.loops.grade
            buffer = fine.buffer
            stored_dalpha, stored_dt = self.stored_dalpha, self.stored_dt
            stored, capacity = buffer.count, buffer.capacity
            passes_done = fine.passes_done
            vrw2, arw2 = pow(grade.acc_vrw_ms_rts, 2.0), pow(grade.gyro_arw_rad_rts, 2.0)
        cdef double key[KEY]
        cdef double Q[64]
        cdef double dalpha[3]
        cdef double beta[3]
        cdef double C[9]
        cdef double gained[2]
        cdef double level_s, azimuth_s, t_end, elapsed_s, dt_s
        cdef const double* F
        cdef const double* a
        cdef int stage = STOP_DONE
        cdef Py_ssize_t stepped = -1   # the last sample whose control step was taken
        for i in range(64):
            Q[i] = 0.0
        with nogil:   # the reading thread of a replay parses meanwhile
            while c < limit:
                # the block's observations: folded, then measured
                upto = fold_end[c]
                if resume and c == b:
                    pass
                elif upto > folded:
                    _fold(K, &dK[folded, 0, 0], &trace_R[folded], upto - folded, &m, &trace_P, &n_obs, &rho,
                          self.trace_Q, self.policy, self.fixed_rho)
                    folded = upto
                    q_known = False
                if self.with_noise and folded > measured:
                    outliers += _hadamard_feed(self.lat, self.gravity, &observed_s[measured],
                                               &observed_alpha[measured, 0], folded - measured, &alpha_sum[0, 0],
                                               &beta_sum[0, 0], alpha_sum.shape[0], &moments[0], &lags[0],
                                               lags.shape[0], &sums[0], &counts[0],
                                               C_rough if with_rough else NULL, &steps, &bad_until, self.settle_steps,
                                               self.outlier_factor, self.min_outlier_count, self.verdict_steps,
                                               &verdict_due)
                measured = folded
                if verdict_due:
                    stage = STOP_VERDICT
                    break
                if self.with_fine and ((active and stored == capacity - 1 and not passes_done) or (
                        not active and _handover_due(self.handover == 1, self.handover_time_s, self.handover_min_s,
                                                     self.handover_sigma_deg, self.sigma_unknown_deg, self.efficiency,
                                                     elapsed[ends[c]], n_obs, handover_terms))):
                    stage = STOP_CONTROL   # the hand-over, or the step that fills the store (the passes start)
                    break
                # the control step: Δα and Δ since the last one
                e = ends[c]
                t_end, elapsed_s = t[e], elapsed[e]
                for i in range(3):
                    dalpha[i] = alpha[e, i] - alpha_step[i]
                    alpha_step[i] = alpha[e, i]
                dt_s = t_end - t_step
                t_step = t_end
                stepped = e
                if self.with_fine:   # FineAlignment.feed: the store
                    if stored < capacity:
                        for i in range(3):
                            stored_dalpha[stored, i] = dalpha[i]
                        stored_dt[stored] = dt_s
                        stored += 1
                        passes_done = passes_done or (not active and stored == capacity)   # the loops start too late
                if active:   # CompassLoops.step: the schedule's gains, the azimuth switch, F, Q, the step
                    level_s = _geometric(self.knots, self.level_sigma, self.n_knots, t_loop_s)
                    azimuth_s = _geometric(self.knots, self.azimuth_sigma, self.n_knots, t_loop_s)
                    _level_gains(level_s, self.loops_gravity, self.radius_m, &key[0])
                    if azimuth_s > 0.0 and not azimuth_on:
                        azimuth_on, I_N, y = True, 0.0, 0.0
                    if azimuth_on:
                        key[3] = 1.0
                        _azimuth_gains(azimuth_s, self.loops_gravity, self.radius_m, &key[4])
                    else:
                        key[3] = key[4] = key[5] = key[6] = key[7] = 0.0
                    key[8], key[9] = earth_sign, dt_s
                    F = self._transition_of(key)
                    _process_noise(vrw2, arw2, dt_s, Q)
                    _step(&C_b0_p[0, 0], &V[0], &I_E, &I_N, &y, dalpha, dt_s, key[0], key[1], key[2], azimuth_on,
                          key[4], key[5], key[6], key[7], earth_sign, self.omega_ie_n, self.omega_cos, self.omega_sin,
                          self.radius_m, F, Q, &P[0, 0])
                    t_loop_s += dt_s
                if self.with_motion and elapsed_s >= next_check_s:
                    next_check_s = elapsed_s + self.check_interval_s
                    if n_obs != 0:   # MotionMonitor.check, the base still: the entry stored, the window's velocity
                        if not q_known:
                            _top_quaternion(K, q)
                            q_known = q_new = True
                        _dcm(q[0], q[1], q[2], q[3], C)
                        slot = ring_count % (self.ring_n + 1)
                        oldest = (ring_count + 1) % (self.ring_n + 1)
                        _beta_fixed(self.lat, self.gravity, elapsed_s, beta)
                        a = &alpha_step[0]
                        if ring_count + 1 > self.ring_n:
                            _horizontal(self.lat, elapsed_s, &ring_C[oldest, 0, 0], a, beta, &ring_alpha[oldest, 0],
                                        &ring_beta[oldest, 0], gained)
                            speed = gained[0]
                            if speed > self.suspect_mps + self.suspect_mps_per_s * elapsed_s:
                                stage = STOP_MOTION   # the monitor's Python steps take the check from here
                                break
                        ring_elapsed[slot] = elapsed_s
                        for i in range(3):
                            ring_beta[slot, i] = beta[i]
                            ring_alpha[slot, i] = a[i]
                            for j in range(3):
                                ring_C[slot, i, j] = C[3 * i + j]
                        ring_count += 1
                        if ring_count > self.ring_n:
                            window_speed = speed
                            checked = True
                c += 1
        # the state back into its objects
        # the quaternion of K where the loop solved for it after its last fold, else as it was, unless K was folded
        q_out = None
        if q_known:
            q_out = np.array([q[0], q[1], q[2], q[3]]) if q_new else known
        solver.load(K_out, m, trace_P, n_obs, rho, q_out)
        if self.with_noise:
            noise.steps, noise.bad_until = steps, bad_until
            noise.outliers += outliers
        if self.with_motion:
            motion.ring_count = ring_count
            if checked:
                motion.window_speed_mps, motion.suspect = window_speed, False
        if self.with_fine:
            if active:
                state.I_E, state.I_N, state.y, state.t_loop_s = I_E, I_N, y, t_loop_s
                state.azimuth_on = azimuth_on
            buffer.count = stored
            fine.passes_done = passes_done
        return c, stage, folded, self.alpha_array[stepped] if stepped >= 0 else step_alpha, t_step, next_check_s



def handover_due(bint by_time, double time_s, double least_s, double sigma_deg, double unknown_deg, double efficiency,
                 double elapsed_s, long n_obs, terms) -> bool:
    """Whether the coarse stage hands over to the compass loops (_policy.pxi ``_handover_due``; ``terms`` those of
    FixedBase.handover_terms): the rule the compiled loop applies, for the Python steps."""
    cdef double held[COARSE_TERMS + 2]
    cdef int i
    for i in range(COARSE_TERMS + 2):
        held[i] = terms[i]
    return _handover_due(by_time, time_s, least_s, sigma_deg, unknown_deg, efficiency, elapsed_s, n_obs, held)


def noise_part(double sigma_deg, double bias_rad, double efficiency) -> float:
    """The noise part (rad) of a coarse σ (deg) with the bias limit ``bias_rad`` (_policy.pxi ``_noise_part``)."""
    return _noise_part(sigma_deg, bias_rad, efficiency)
