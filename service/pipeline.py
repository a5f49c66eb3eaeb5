"""The alignment pipeline: IMU samples in, result records at the output epochs out.

It owns the policy around the estimators: which solver, when to emit (epochs on the IMU
samples at whole multiples of the output period), the phase and the ``converged`` flag
(``heading_sigma_deg`` at or below the configured threshold). The estimators stay pure.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..protocol.imu_log import IMU_WIDTH
from ..protocol.results import ResultRecord
from .align.coarse import AttitudeSolution, InertialCoarseAlignment
from .align.compass import GainSchedule
from .align.conventions import DEG, dcm_from_quat, euler_from_dcm, quat_from_dcm, with_heading_of
from .align.disturbance import MotionMonitor
from .align.earth import Site
from .align.fine import FineAlignment
from .align.noise_check import VERDICT_STEPS, NoiseMeter
from .align.observations import FixedSiteSource
from .align.sensor_model import ESTIMATOR_EFFICIENCY, SensorGrade, auto_solver, bias_limit_rad
from .align.solvers import CentredWahba, RecursiveK, make_solver
from .align.swing_bias import SwingBias
from .config import Config, ConfigError

INITIAL_TILT_SIGMA_DEG = 0.1
INITIAL_HEADING_SIGMA_DEG = 1.5
"""1-sigma errors assumed for an attitude given from outside (compass alone, seed 001's start)."""
AID_EPOCH_COLUMN = IMU_WIDTH
"""The layout of the samples the pipeline holds: the IMU row (t, Δθ (3), Δv (3)); an aided pipeline's then the aiding
epoch's number and the aiding values (``aid_width``)."""


def grade_from(config: Config, datasheet: dict[str, float] | None = None) -> SensorGrade:
    """The sensor grade of the configuration, with a log's datasheet keys taking precedence."""
    figures = {**{k: getattr(config.sensor, k) for k in ("gyro_bias_deg_h", "gyro_arw_deg_rth", "acc_bias_ug",
                                                          "acc_vrw_ug_rthz")}, **(datasheet or {})}
    return SensorGrade.from_datasheet(**figures)


def result_record(solution: AttitudeSolution, t_epoch: float, phase: str, threshold_deg: float) -> ResultRecord:
    """The pinned result of one solution, stamped with its output epoch."""
    heading, pitch, roll = euler_from_dcm(dcm_from_quat(solution.q_b_n))
    heading_deg = float(heading / DEG) % 360.0
    q = tuple(float(c) for c in solution.q_b_n / np.linalg.norm(solution.q_b_n))
    return ResultRecord(t=t_epoch, phase=phase, q=q, pitch_deg=float(pitch / DEG), roll_deg=float(roll / DEG),
                        heading_deg=heading_deg if heading_deg < 360.0 else 0.0,
                        heading_sigma_deg=solution.heading_sigma_deg, level_sigma_deg=solution.level_sigma_deg,
                        converged=bool(solution.heading_sigma_deg <= threshold_deg), rho=float(solution.rho),
                        trace_P=float(solution.trace_P), n_obs=solution.n_obs)


def smaller_sigma_solution(coarse: AttitudeSolution, C_fine: np.ndarray, fine_heading_sigma_deg: float,
                           fine_level_sigma_deg: float) -> AttitudeSolution:
    """The output once the loops run beside the coarse stage (which runs on): the level of whichever of the two
    claims the smaller level σ, the heading of whichever claims the smaller heading σ, each with its σ. So the fine
    stage never makes either worse than the coarse stage alone would give (a 600-s least-squares heading can beat a
    narrow loop, while the loops hold the level that the inertial-frame fit lets drift by ε·T)."""
    C_coarse = dcm_from_quat(coarse.q_b_n)
    level_fine = fine_level_sigma_deg < coarse.level_sigma_deg
    heading_fine = fine_heading_sigma_deg < coarse.heading_sigma_deg
    if not level_fine and not heading_fine:
        return coarse
    C_level = C_fine if level_fine else C_coarse
    C_b_n = C_level if level_fine == heading_fine else with_heading_of(C_level, C_fine if heading_fine else C_coarse)
    return replace(coarse, q_b_n=quat_from_dcm(C_b_n),
                   heading_sigma_deg=min(fine_heading_sigma_deg, coarse.heading_sigma_deg),
                   level_sigma_deg=min(fine_level_sigma_deg, coarse.level_sigma_deg))


def _fold_until(solver: RecursiveK | CentredWahba, due: np.ndarray, dK: np.ndarray, trace_R: np.ndarray, folded: int,
                sample: int) -> int:
    """Fold the prepared observations taken at samples up to ``sample``; returns how many are folded."""
    upto = int(np.searchsorted(due, sample, side="right"))
    if upto > folded:
        solver.fold(dK[folded:upto], trace_R[folded:upto])
    return upto


class AlignmentPipeline:
    """Coarse then fine alignment of a base fixed in position, emitting records at the output epochs.

    Samples are processed in canonical blocks of ``block_samples`` (one compass control step),
    counted from the first sample; an incomplete block waits for its last sample. Every block
    therefore sees the same arithmetic whether the samples come one at a time (daemon) or in
    large chunks (replay), and the results are bit-identical. A record whose epoch sample waits in
    an incomplete block is computed at once on a scratch copy (same bits, see
    :meth:`_emit_from_pending`), so every record leaves with the call that brought its sample.

    Parameters
    ----------
    config : validated configuration.
    site : position of the IMU.
    rate_hz : nominal IMU sample rate.
    datasheet : the log's datasheet keys, if any (override ``config.sensor``).
    live : slice the stored-data passes into ``fine.live_pass_steps`` steps per block instead of
        running them at once (offline).
    initial_q_b_n : start the compass loops at once from this attitude at the first sample
        (compass alone, for evaluation), skipping the coarse stage.
    """

    aid_width = 0
    """Aiding values per sample that :meth:`process` takes (0: none; aided pipelines set it)."""
    aid_kind = ""
    """The aiding kind of those values (``odo``, ``gnss``, ``master``): the prefix of its status counters."""
    checks_translation = True
    """Whether a base that translates is a disturbance (not for a base meant to move)."""
    checks_noise = True
    """Whether σ takes the noise the fixed-base residual shows (service/align/noise_check.py; a moving vehicle's
    σ comes from its fits and filters)."""

    def __init__(self, config: Config, site: Site, rate_hz: float, datasheet: dict[str, float] | None = None,
                 live: bool = False, initial_q_b_n: np.ndarray | None = None) -> None:
        a, f = config.alignment, config.fine
        self.config = config
        self.sample_period_s = 1.0 / rate_hz
        if a.obs_interval_s < self.sample_period_s:
            raise ConfigError(f"alignment.obs_interval_s: {a.obs_interval_s} s is shorter than the IMU sample "
                              f"period {self.sample_period_s:g} s ({rate_hz:g} Hz)")
        self.period_s = config.output.period_s
        self.site = site
        self.grade = grade_from(config, datasheet)
        # the coarse solver that runs: alignment.solver, or the one "auto" picks for this datasheet
        self.solver_name = (auto_solver(self.grade, site.lat, site.gravity, a.converged_heading_sigma_deg)
                            if a.solver == "auto" else a.solver)
        self.sigma_grade = self.grade   # the datasheet's, until the data show their own noise (noise_check.py)
        self.noise_unchecked = self.checks_noise   # σ still waits for the meter's first verdict
        self.block_samples = max(1, round(f.control_interval_s * rate_hz))
        self._live = live
        self._with_fine = f.enabled or initial_q_b_n is not None
        self._start_estimators()
        self.disturbances = 0
        self.last_disturbance: str | None = None
        self.last_notice: str | None = None   # why the alignment cannot go on as configured, for the operator
        self._disturbed_until = -np.inf   # a restarted alignment is disturbed until then
        self._initial_C_b_n = None if initial_q_b_n is None else dcm_from_quat(np.asarray(initial_q_b_n, float))
        self._pending = np.empty((self.block_samples, AID_EPOCH_COLUMN + (1 + self.aid_width if self.aid_width else 0)))
        self._n_pending = 0
        self._epoch_count: int | None = None
        self._emitted_count = -(2**62)

    def _start_estimators(self, t_start: float | None = None) -> None:
        """Fresh coarse and fine stages, from the start of the data or from ``t_start`` (a restart)."""
        self.coarse = self._make_coarse()
        self.fine = self._make_fine()
        self._apply_sigma_grade()
        self._alpha_step = np.zeros(3)
        self._t_step = t_start
        self._step_epoch = -1.0   # the newest aiding epoch at the last control step
        self._restarted = t_start is not None
        d = self.config.disturbance
        self.motion = (MotionMonitor(self.coarse.source, d.velocity_threshold_mps, d.window_s, d.check_interval_s,
                                     d.hold_s) if d.enabled and self.checks_translation else None)
        self._next_check_s = d.check_interval_s
        # the meter's α history lives in these estimators' b0 axes (the figures found so far stay in sigma_grade)
        self.noise = (NoiseMeter(self.config.alignment.obs_interval_s, self.site.lat, self.site.gravity)
                      if self.checks_noise else None)

    def aiding_counters(self) -> dict[str, int]:
        """What the estimators made of the aiding (none without): coarse observations due before the aid's first
        value (``<kind>_observations_awaiting_aid``, a wait) and after it without one (``…_unaided_observations``,
        a dropout); aided pipelines add their estimators' counts."""
        if not self.aid_width:
            return {}
        return {f"{self.aid_kind}_observations_awaiting_aid": self.coarse.observations_awaiting_aid,
                f"{self.aid_kind}_unaided_observations": self.coarse.unaided_observations}

    @property
    def awaiting_aid(self) -> bool:
        """An aided pipeline whose aid has not given its first value yet: the alignment has not started."""
        return bool(self.aid_width) and not self.coarse.aid_started

    def carry_aid_start(self, previous: AlignmentPipeline) -> None:
        """A fresh pipeline that replaces ``previous`` (a restart after an outage): an aid that had begun there stays
        begun here, so an observation without it is a dropout, not a wait."""
        self.coarse.aid_started = self.coarse.aid_started or previous.coarse.aid_started

    def stages_text(self) -> str:
        """The stages that run, for the operator's log: the coarse solver ("auto" says what it chose), the swing-bias
        fit and the compass stage; an aided pipeline names its aid (its stages are its own)."""
        if self.aid_width:
            return f"{self.aid_kind}-aided alignment"
        a = self.config.alignment
        solver = self.solver_name
        if a.solver == "auto":
            solver += f" (auto: {'gyro walk' if solver == 'gls' else 'accelerometer noise'} dominates)"
        return (f"coarse solver {solver}, swing-bias fit {'on' if a.swing_bias else 'off'}, "
                f"compass stage {'on' if self._with_fine else 'off'}")

    def _make_coarse(self) -> InertialCoarseAlignment:
        a = self.config.alignment
        solver = make_solver(self.solver_name, a.request_rho, self.grade, self.site.gravity, a.disturbance_velocity_mps)
        swing_bias = (SwingBias(self.site.lat, self.grade.acc_bias_ms2, self.grade.acc_vrw_ms_rts) if a.swing_bias
                      else None)
        return InertialCoarseAlignment(FixedSiteSource(self.site), self.grade, solver, self.sample_period_s,
                                       a.obs_interval_s, a.disturbance_velocity_mps, swing_bias)

    def _make_fine(self) -> FineAlignment | None:
        if not self._with_fine:
            return None
        f = self.config.fine
        return FineAlignment(self.site, self.grade, GainSchedule(f.schedule_time_s, f.level_sigma, f.azimuth_sigma),
                             self.block_samples * self.sample_period_s, f.stored_data_s, f.stored_pairs,
                             f.live_pass_steps if self._live else None)

    def _epoch_counts(self, t: np.ndarray) -> np.ndarray:
        # the sample within half a period of k·P carries epoch k
        return np.floor((t + 0.5 * self.sample_period_s) / self.period_s).astype(np.int64)

    def process(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray,
                aid: np.ndarray | None = None) -> list[ResultRecord]:
        """Feed N samples (t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s, and for an aided pipeline the aiding at the
        samples, aid (N, 1 + ``aid_width``): the number of the newest aiding epoch at or before the sample, then
        the values, NaN where none (:meth:`AidingTrack.aid_at`)); return the records they complete."""
        t = np.asarray(t, dtype=float).reshape(-1)
        if len(t) == 0:
            return []
        columns = [t, np.reshape(dtheta, (-1, 3)), np.reshape(dv, (-1, 3))]
        if self.aid_width:
            columns.append(np.reshape(aid, (-1, 1 + self.aid_width)))
        samples = np.column_stack(columns)
        if self._epoch_count is None:
            self._epoch_count = int(self._epoch_counts(np.asarray([t[0] - self.sample_period_s]))[0])
            self._t_step = float(t[0]) - self.sample_period_s
        records: list[ResultRecord] = []
        M, i = self.block_samples, 0
        if self._n_pending:
            i = min(M - self._n_pending, len(samples))
            self._pending[self._n_pending:self._n_pending + i] = samples[:i]
            self._n_pending += i
            if self._n_pending == M:
                self._process_blocks(self._pending, records)
                self._n_pending = 0
        whole = (len(samples) - i) // M * M
        if whole:
            self._process_blocks(samples[i:i + whole], records)
        rest = samples[i + whole:]
        self._pending[:len(rest)] = rest
        self._n_pending += len(rest)
        self._emit_from_pending(records)
        return records

    def _emit_from_pending(self, records: list[ResultRecord]) -> None:
        """Records whose epoch sample waits in the incomplete block, computed on a scratch copy.

        The scan and the fold give a prefix of a block the same bits as the whole block, so these
        records equal what the complete block would emit; the block then skips them.
        """
        pending = self._pending[:self._n_pending]
        counts = self._epoch_counts(pending[:, 0])
        new = np.flatnonzero((np.diff(counts, prepend=self._epoch_count) > 0) & (counts > self._emitted_count))
        if len(new) == 0:
            return
        scratch = self.coarse.scratch()
        elapsed, q_b_b0, alpha = scratch.integrate(pending[:, 0], pending[:, 1:4], pending[:, 4:7])
        due, dK, trace_R = scratch.observe(elapsed, q_b_b0, alpha, self._aid(pending), self._aid_epoch(pending))
        folded = 0
        for j in new:
            folded = _fold_until(scratch.solver, due, dK, trace_R, folded, j)
            records.append(self._record(round(float(counts[j]) * self.period_s, 9), float(pending[j, 0]), q_b_b0[j],
                                        scratch))
        self._emitted_count = int(counts[new[-1]])

    def _process_blocks(self, samples: np.ndarray, records: list[ResultRecord]) -> None:
        """Whole blocks: integrate them at once, then per block fold the observations, emit, control."""
        M = self.block_samples
        t = samples[:, 0]
        elapsed, q_b_b0, alpha = self.coarse.integrate(t, samples[:, 1:4], samples[:, 4:7], M)
        aid, aid_epoch = self._aid(samples), self._aid_epoch(samples)
        due, dK, trace_R = self.coarse.observe(elapsed, q_b_b0, alpha, aid, aid_epoch)
        observed_s, observed_alpha = self.coarse.observed
        counts = self._epoch_counts(t)
        epochs = np.flatnonzero(np.diff(counts, prepend=self._epoch_count) > 0)
        self._epoch_count = int(counts[-1])
        folded = 0
        solver = self.coarse.solver
        for end in range(M - 1, len(t), M):
            for j in epochs[(epochs > end - M) & (epochs <= end)]:
                folded = _fold_until(solver, due, dK, trace_R, folded, j)
                if counts[j] > self._emitted_count:
                    records.append(self._record(round(float(counts[j]) * self.period_s, 9), float(t[j]), q_b_b0[j],
                                                self.coarse))
                    self._emitted_count = int(counts[j])
            measured, folded = folded, _fold_until(solver, due, dK, trace_R, folded, end)
            if self.noise is not None:   # after the block's records: a record in an incomplete block sees the same
                self._measure_noise(observed_s[measured:folded], observed_alpha[measured:folded])
            self._control_step(float(t[end]), float(elapsed[end]), q_b_b0[end], alpha[end],
                               None if aid is None else aid[end], None if aid_epoch is None else aid_epoch[end])
            if self._restarted:   # new estimators: they integrate the rest of the chunk themselves
                self._restarted = False
                if end + 1 < len(t):
                    self._process_blocks(samples[end + 1:], records)
                return

    def _measure_noise(self, elapsed_s: np.ndarray, alpha: np.ndarray) -> None:
        """Feed one block's observations (elapsed (M,) s, α (M, 3) m/s) to the noise meter; every
        :data:`VERDICT_STEPS` observations σ takes the figures the data show (service/align/noise_check.py), and the
        operator is told once of a datasheet far too quiet."""
        verdict_due = False
        for elapsed_k, alpha_k in zip(elapsed_s, alpha, strict=True):
            self.noise.feed(float(elapsed_k), alpha_k)
            verdict_due = verdict_due or self.noise.steps % VERDICT_STEPS == 0
        if not verdict_due:
            return
        if self.coarse.solver.n_obs:
            self.noise.C_n0_b0 = dcm_from_quat(self.coarse.q_b_n0).T
        verdict = self.noise.verdict(self.grade)
        self.noise_unchecked = self.noise_unchecked and verdict is None
        if verdict is not None and verdict.grade != self.sigma_grade:
            self.sigma_grade = verdict.grade
            self._apply_sigma_grade()
            self.last_notice = self.last_notice or verdict.notice

    def _apply_sigma_grade(self) -> None:
        """The stages report σ with :attr:`sigma_grade` (their estimates keep the datasheet's weights and gains). The
        loops take it until they start: their covariance then runs on with one grade, so live passes sliced over
        many steps propagate it as offline passes run at once do."""
        self.coarse.sigma_grade = self.sigma_grade
        if isinstance(self.fine, FineAlignment) and not self.fine.active:
            self.fine.loops.grade = self.sigma_grade

    def _aid(self, samples: np.ndarray) -> np.ndarray | None:
        """The aiding values of the samples (N, ``aid_width``), None without aiding."""
        return samples[:, AID_EPOCH_COLUMN + 1:] if self.aid_width else None

    def _aid_epoch(self, samples: np.ndarray) -> np.ndarray | None:
        """The number (N,) of the newest aiding epoch at or before each sample (NaN: none), None without aiding."""
        return samples[:, AID_EPOCH_COLUMN] if self.aid_width else None

    def _control_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, alpha: np.ndarray,
                      aid: np.ndarray | None, aid_epoch: float | None) -> None:
        dalpha, dt_s = alpha - self._alpha_step, t_end - self._t_step
        self._alpha_step, self._t_step = alpha, t_end
        # one Kalman update per aiding epoch: a slower aid interpolated over several steps is one measurement
        fresh = aid_epoch is not None and aid_epoch > self._step_epoch
        if fresh:
            self._step_epoch = aid_epoch
        self._stage_step(t_end, elapsed_s, q_b_b0, dalpha, dt_s, aid, fresh)
        if self.motion is not None and elapsed_s >= self._next_check_s:
            self._next_check_s = elapsed_s + self.config.disturbance.check_interval_s
            self._check_motion(t_end, elapsed_s, q_b_b0, alpha)

    def _check_motion(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, alpha: np.ndarray) -> None:
        """Watch for a base that translates (:class:`MotionMonitor`) under the coarse estimate, which runs through
        every stage: while it moves the records are ``disturbed`` with the trusted attitude carried on by the gyros;
        once it is at rest again the alignment restarts if the data contradict it (``action = "restart"``)."""
        if self.coarse.solver.n_obs == 0:
            return
        heading_deg, level_deg = self.coarse.sigma(elapsed_s)
        found = self.motion.check(elapsed_s, alpha, q_b_b0, dcm_from_quat(self.coarse.q_b_n0), heading_deg * DEG,
                                  level_deg * DEG)
        if found is None:
            return
        d = self.config.disturbance
        if found.state == "moving":
            if self.motion.episode.detected_s == elapsed_s:
                self.disturbances += 1
                self.last_disturbance = (f"base moving at t = {t_end:.2f} s: {found.speed_mps:.2f} m/s gained in "
                                         f"{d.window_s:g} s (> {d.velocity_threshold_mps:g} m/s); the gyros carry "
                                         "the last trusted attitude on until it is at rest again")
            return
        restart = found.restart and d.action == "restart"
        self.last_disturbance = (f"base at rest again at t = {t_end:.2f} s after gaining up to {found.speed_mps:.2f} "
                                 "m/s: " + ("alignment restarted" if restart else
                                            "alignment kept (consistent with the data)" if not found.restart else
                                            "alignment not restarted (disturbance.action = report)"))
        if restart:
            self._disturbed_until = t_end + d.hold_s
            self._start_estimators(t_end)

    def _stage_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray,
                    dt_s: float, aid: np.ndarray | None, fresh: bool) -> None:
        """One control step's stage work: Δα (3,) m/s over ``dt_s`` ending at ``t_end``; ``aid`` the aiding values at
        the step's end, ``fresh`` whether they come from an aiding epoch newer than the last step's."""
        if self.fine is None:
            return
        if not self.fine.active and self._initial_C_b_n is not None:
            self.fine.start(self._initial_C_b_n, np.eye(3), *self._initial_sigma())
        self.fine.feed(dalpha, dt_s)
        if not self.fine.active and self._handover_due(elapsed_s):
            solution = self.coarse.solution_at(t_end, q_b_b0)
            noise = self._noise_part(solution.heading_sigma_deg, solution.level_sigma_deg)
            self.fine.start(dcm_from_quat(solution.q_b_n), dcm_from_quat(q_b_b0), *noise,
                            t_loop_s=self.config.fine.handover_schedule_s)

    def _handover_due(self, elapsed_s: float) -> bool:
        f = self.config.fine
        if f.handover == "time":
            return elapsed_s >= f.handover_time_s
        if self.coarse.solver.n_obs == 0 or elapsed_s < f.handover_min_s or self.noise_unchecked:
            # a datasheet that claims far too little noise would hand over at the first observation, before the
            # heading is known at all, and the loops cannot pull in a large error; nor may the loops start from a
            # σ the data's own noise has not checked yet (they carry it on)
            return False
        # the noise part only: the bias floor stays whatever the stage, and above the threshold
        # for a poor gyro it would keep the loops from ever starting
        return self._noise_part(*self.coarse.sigma(elapsed_s))[1] / DEG <= f.handover_sigma_deg

    def _noise_part(self, heading_sigma_deg: float, level_sigma_deg: float) -> tuple[float, float]:
        """1-sigma (tilt, heading) noise errors (rad) of a coarse solution: its σ without the bias limit.

        Both are divided by the efficiency factor the reported σ carries, to seed the loops' covariance.
        """
        grade, site = self.coarse.grade, self.coarse.source.site
        bias_heading, bias_level = bias_limit_rad(grade, site.lat, site.gravity)
        tilt2 = max((level_sigma_deg * DEG) ** 2 - bias_level**2, 0.0)
        heading2 = max((heading_sigma_deg * DEG) ** 2 - bias_heading**2, 0.0)
        return float(np.sqrt(tilt2 / ESTIMATOR_EFFICIENCY)), float(np.sqrt(heading2 / ESTIMATOR_EFFICIENCY))

    def _initial_sigma(self) -> tuple[float, float]:
        return INITIAL_TILT_SIGMA_DEG * DEG, INITIAL_HEADING_SIGMA_DEG * DEG

    def _record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
                coarse: InertialCoarseAlignment) -> ResultRecord:
        episode = None if self.motion is None else self.motion.episode
        if episode is not None:
            # a base that moves: the attitude trusted before the motion, carried on by the gyros
            elapsed = t_sample - coarse.t0
            C_b_n = coarse.source.C_n_n0(elapsed).T @ episode.C_b0_n0 @ dcm_from_quat(q_b_b0)
            solution = AttitudeSolution(t_sample, quat_from_dcm(C_b_n), episode.heading_sigma_rad / DEG,
                                        episode.level_sigma_rad / DEG, coarse.solver.rho, coarse.solver.trace_P,
                                        coarse.solver.n_obs)
            record = result_record(solution, t_epoch, "disturbed", self.config.alignment.converged_heading_sigma_deg)
        else:
            record = self._stage_record(t_epoch, t_sample, q_b_b0, coarse)
        if episode is not None or t_sample < self._disturbed_until:
            # nothing converged survives a disturbance until the restarted alignment earns it again
            return replace(record, phase="disturbed", converged=False)
        if record.converged and self.motion is not None and self.motion.suspect:
            return replace(record, converged=False)   # a base that may be starting to move
        return record

    def _stage_record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
                      coarse: InertialCoarseAlignment) -> ResultRecord:
        threshold = self.config.alignment.converged_heading_sigma_deg
        if self.fine is None or not self.fine.active:
            record = result_record(coarse.solution_at(t_sample, q_b_b0), t_epoch, "coarse", threshold)
            # without a fine stage, a converged coarse solution is the end of the alignment
            return replace(record, phase="aligned") if self.fine is None and record.converged else record
        sigma = self.fine.sigma
        solution = coarse.solution_at(t_sample, q_b_b0)
        C_fine = self.fine.attitude(dcm_from_quat(q_b_b0), t_sample - self._t_step)
        if self._initial_C_b_n is not None:
            # a compass-alone start from a given attitude (evaluation) is the loops' alone
            solution = AttitudeSolution(t_sample, quat_from_dcm(C_fine), sigma.heading_deg, sigma.level_deg,
                                        coarse.solver.rho, coarse.solver.trace_P, coarse.solver.n_obs)
        else:
            solution = smaller_sigma_solution(solution, C_fine, sigma.heading_deg, sigma.level_deg)
        aligned = self.fine.schedule_complete and solution.heading_sigma_deg <= threshold
        return result_record(solution, t_epoch, "aligned" if aligned else "fine", threshold)
