"""The alignment pipeline: IMU samples in, result records at the output epochs out.

It owns the policy around the estimators: which solver, when to emit (epochs on the IMU
samples at whole multiples of the output period), the phase and the ``converged`` flag
(``heading_sigma_deg`` at or below the configured threshold). The estimators stay pure.
"""
from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable, Iterable
from dataclasses import replace
from functools import partial
from typing import Protocol

import numpy as np

from ..protocol.imu_log import IMU_WIDTH
from ..protocol.results import ResultRecord
from .align._blocks import CONTROL, DONE, MOTION, VERDICT, FixedBaseBlocks
from .align._strapdown import rows_offset
from .align.coarse import AttitudeSolution, InertialCoarseAlignment, stepped_up
from .align.consistency import ConsistencyMonitor
from .align.conventions import DEG, dcm_from_quat, quat_from_dcm
from .align.disturbance import MotionMonitor
from .align.earth import Site
from .align.fine import FineAlignment
from .align.noise_check import MIN_OUTLIER_COUNT, OUTLIER_FACTOR, SETTLE_S, VERDICT_STEPS, NoiseMeter
from .align.sensor_model import (
    ESTIMATOR_EFFICIENCY,
    SIGMA_UNKNOWN_DEG,
    AttitudeSigma,
    SensorGrade,
    auto_solver,
    carried_sigma,
    inertial_alignment_sigma,
    inertial_alignment_sigmas,
)
from .align.solvers import _GAIN_POLICY, CentredWahba, RecursiveK
from .align.turns import TURN_WINDOW_S, TURNED, TurnWatch
from .config import Config, ConfigError
from .modes import MODES
from .modes.fixed_base import FixedBase
from .records import result_record

AID_COLUMN = IMU_WIDTH
"""The layout of the samples the pipeline holds: the IMU row (t, Δθ (3), Δv (3)); an aided pipeline's then, per aiding
kind of its mode (``Mode.aids``, in that order), the number of the kind's newest epoch and its values."""


_NONE_FRESH = np.zeros(0, bool)
_NONE_FRESH.flags.writeable = False
"""The fresh-epoch flags of a pipeline without aiding (no kinds)."""


def grade_from(config: Config, datasheet: dict[str, float] | None = None) -> SensorGrade:
    """The sensor grade of the configuration, with a log's datasheet keys taking precedence."""
    figures = {**{k: getattr(config.sensor, k) for k in ("gyro_bias_deg_h", "gyro_arw_deg_rth", "acc_bias_ug",
                                                          "acc_vrw_ug_rthz")}, **(datasheet or {})}
    return SensorGrade.from_datasheet(**figures)


def _imu_rows(t: np.ndarray, dtheta: object, dv: object) -> np.ndarray | None:
    """A read-only (N, 7) view of the rows (t, Δθ, Δv) that ``t``, ``dtheta`` and ``dv`` are the columns of (a log
    reader's block), for the pipeline to read in place; None for any other layout (then copied)."""
    owner = getattr(t, "base", None)
    if (owner is None or owner is not getattr(dtheta, "base", None) or owner is not getattr(dv, "base", None)
            or t.dtype != np.float64 or dtheta.dtype != np.float64 or dv.dtype != np.float64
            or (offset := rows_offset(owner, t, dtheta, dv)) < 0):
        return None
    rows = np.ndarray((len(t), IMU_WIDTH), np.float64, owner, offset, (IMU_WIDTH * 8, 8))
    rows.flags.writeable = False
    return rows


def _fold_to(solver: RecursiveK | CentredWahba, dK: np.ndarray, trace_R: np.ndarray, folded: int, upto: int) -> int:
    """Fold the prepared observations ``folded`` to ``upto`` (those taken up to a sample: ``np.searchsorted(due,
    sample, side="right")``); returns how many are folded."""
    if upto > folded:
        solver.fold(dK[folded:upto], trace_R[folded:upto])
    return upto


UNTOUCHED = -1
"""A block the compiled loop has not begun (:mod:`~service.align._blocks`' stages)."""
CONTRADICTED = -2
"""A block whose records contradicted the earlier estimates: the alignment restarts at its end, unfolded."""


def fixed_base_blocks(pipeline: AlignmentPipeline) -> FixedBaseBlocks | None:
    """The compiled loop over the control steps of a fixed-base pipeline's fresh estimators (None for any other: an
    aided mode, another solver, a start from a given attitude)."""
    fine = pipeline.fine
    if (type(pipeline.mode) is not FixedBase or pipeline.aid_width or pipeline.initial_C_b_n is not None
            or type(pipeline.coarse.solver) is not RecursiveK or not (fine is None or isinstance(fine, FineAlignment))):
        return None
    noise = pipeline.noise
    settle = round(SETTLE_S / noise.step_s) if noise is not None else 0
    solver = pipeline.coarse.solver
    motion = pipeline.motion
    suspect = motion.suspect_line if motion is not None else (0.0, 0.0)   # a window's velocity that asks for σ
    return FixedBaseBlocks(pipeline.site.lat, pipeline.site.gravity, solver, _GAIN_POLICY[solver.solver], noise,
                           (settle, OUTLIER_FACTOR, MIN_OUTLIER_COUNT, VERDICT_STEPS), motion, *suspect,
                           pipeline.config.disturbance.check_interval_s, fine, pipeline.config.fine.compass,
                           SIGMA_UNKNOWN_DEG, ESTIMATOR_EFFICIENCY)


class Mode(Protocol):
    """What a mode declares (one file per mode under service/modes/, built with its pipeline): the aiding it takes
    (``aids``: each kind with its values per sample, in column order; ``coarse_kind``: the one the coarse stage
    observes; ``gyro_rate``: the gyro rate appended to the values), whether a
    translating base is a disturbance and whether σ takes the noise the data show, its coarse stage (observation
    source, solver, σ model) and fine stage, what each control step does (measurements, hand-over), each output
    epoch's record, its counters and a line for the operator."""

    aids: tuple[tuple[str, int], ...]
    coarse_kind: str
    checks_translation: bool
    checks_noise: bool
    watches_turns: bool
    gyro_rate: bool

    def make_coarse(self) -> InertialCoarseAlignment: ...

    def make_fine(self) -> object | None: ...

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None: ...

    def record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
               coarse: InertialCoarseAlignment) -> ResultRecord: ...

    def counters(self) -> dict[str, int]: ...

    def stages_text(self) -> str: ...


class AlignmentPipeline:
    """Coarse then fine alignment, emitting records at the output epochs; what the stages are is the mode's.

    Samples are processed in canonical blocks of ``block_samples`` (one compass control step),
    counted from the first sample; an incomplete block waits for its last sample. Every block
    therefore sees the same arithmetic whether the samples come one at a time (daemon) or in
    large chunks (replay), and the results are bit-identical. A record whose epoch sample waits in
    an incomplete block is computed at once, from the integrator run ahead or on a scratch copy (same bits, see
    :meth:`_emit_from_pending`), so every record leaves with the call that brought its sample.

    Parameters
    ----------
    config : validated configuration.
    site : position of the IMU.
    rate_hz : nominal IMU sample rate.
    datasheet : the log's datasheet keys, if any (override ``config.sensor``).
    live : slice the stored-data passes into ``fine.compass.live_pass_steps`` steps per block instead of
        running them at once (offline).
    initial_q_b_n : start the compass loops at once from this attitude at the first sample
        (compass alone, for evaluation), skipping the coarse stage.
    mode : the mode's class (:class:`Mode`, built with this pipeline); the fixed base by default.
    """

    def __init__(self, config: Config, site: Site, rate_hz: float, datasheet: dict[str, float] | None = None,
                 live: bool = False, initial_q_b_n: np.ndarray | None = None,
                 mode: Callable[[AlignmentPipeline], Mode] = FixedBase) -> None:
        a, f = config.alignment, config.fine
        self.config = config
        self.sample_period_s = 1.0 / rate_hz
        if a.obs_interval_s < self.sample_period_s:
            raise ConfigError(f"alignment.obs_interval_s: {a.obs_interval_s} s is shorter than the IMU sample "
                              f"period {self.sample_period_s:g} s ({rate_hz:g} Hz)")
        self.period_s = config.output.period_s
        self.site = site
        self._lat_gravity = (site.lat, site.gravity)   # the site's gravity is a formula: once
        self.grade = grade_from(config, datasheet)
        # the coarse solver that runs: alignment.solver, or the one "auto" picks for this datasheet
        self.solver_name = (auto_solver(self.grade, site.lat, site.gravity, a.converged_heading_sigma_deg)
                            if a.solver == "auto" else a.solver)
        self.sigma_grade = self.grade   # the datasheet's, until the data show their own noise (noise_check.py)
        self.block_samples = max(1, round(f.control_interval_s * rate_hz))
        self.live = live
        self.with_fine = f.enabled or initial_q_b_n is not None
        self.initial_C_b_n = None if initial_q_b_n is None else dcm_from_quat(np.asarray(initial_q_b_n, float))
        self.mode = mode(self)
        self.noise_unchecked = self.checks_noise   # σ still waits for the meter's first verdict
        self._dtheta_last = np.zeros(3)   # the last sample's Δθ (rad): the gyro rate of the next one's aid
        self._start_estimators()
        self.disturbances = 0
        self.last_disturbance: str | None = None
        self.last_notice: str | None = None   # why the alignment cannot go on as configured, for the operator
        self._disturbed_until = -np.inf   # a restarted alignment is disturbed until then
        # where each kind's epoch number and values sit in the samples
        widths = [width for _, width in self.mode.aids]
        self._epoch_columns = AID_COLUMN + np.cumsum([0, *widths[:-1]], dtype=int) + np.arange(len(widths))
        self._value_columns = np.concatenate([np.arange(c + 1, c + 1 + w) for c, w in
                                              zip(self._epoch_columns, widths, strict=True)] or [[]]).astype(int)
        self._coarse_index = self.aid_kinds.index(self.mode.coarse_kind) if widths else 0
        self._pending = np.empty((self.block_samples, AID_COLUMN + sum(1 + w for _, w in self.mode.aids)))
        self._n_pending = 0
        self._epoch_count: int | None = None
        self._emitted_count = -(2**62)
        self._defer_control = False
        self._deferred: tuple | None = None   # a block's tail left by process(defer_control=True): see settle()

    def _start_estimators(self, t_start: float | None = None) -> None:
        """Fresh coarse and fine stages, from the start of the data or from ``t_start`` (a restart)."""
        self.coarse = self.mode.make_coarse()
        self.fine = self.mode.make_fine()
        self._apply_sigma_grade()
        self._alpha_step = np.zeros(3)
        self._t_step = t_start
        self._step_epoch = np.full(len(self.mode.aids), -1.0)   # each kind's newest epoch at the last control step
        self._restarted = t_start is not None
        d = self.config.disturbance
        self.motion = (MotionMonitor(self.site, d.velocity_threshold_mps, d.window_s, d.check_interval_s,
                                     d.hold_s, self.grade.gyro_bias_rad_s)
                       if d.enabled and self.checks_translation else None)
        self._next_check_s = d.check_interval_s
        # a fixed base's estimates against their σ (consistency.py); a moving vehicle's fits and filters judge their own
        self.consistency = ConsistencyMonitor() if self.motion is not None and self.checks_noise else None
        self._contradiction: str | None = None   # found at a record; the alignment restarts at its block's end
        # the meter's α history lives in these estimators' b0 axes (the figures found so far stay in sigma_grade)
        self.noise = (NoiseMeter(self.config.alignment.obs_interval_s, self.site.lat, self.site.gravity)
                      if self.checks_noise else None)
        # turns of the base, in these estimators' b0 axes: at each, the fine stage is dropped until it is steady
        self.turns = (TurnWatch(round(TURN_WINDOW_S / (self.block_samples * self.sample_period_s)))
                      if self.mode.watches_turns and self.fine is not None and self.initial_C_b_n is None else None)
        self._turn_events: list[tuple[float, int]] = []   # (the control step's end time s, event), in time order
        self._blocks = fixed_base_blocks(self)

    @property
    def aid_width(self) -> int:
        """Aiding values per sample that :meth:`process` takes, over all its kinds (0: none)."""
        return sum(width for _, width in self.mode.aids)

    @property
    def aid_kinds(self) -> tuple[str, ...]:
        """The aiding kinds (``odo``, ``gnss``, ``master``) of those values, in their column order."""
        return tuple(kind for kind, _ in self.mode.aids)

    @property
    def aid_kind(self) -> str:
        """The aiding kind the coarse stage observes: the prefix of its status counters."""
        return self.mode.coarse_kind

    @property
    def checks_translation(self) -> bool:
        """Whether a base that translates is a disturbance (not for a base meant to move)."""
        return self.mode.checks_translation

    @property
    def checks_noise(self) -> bool:
        """Whether σ takes the noise the fixed-base residual shows (service/align/noise_check.py; a moving vehicle's
        σ comes from its fits and filters)."""
        return self.mode.checks_noise

    @property
    def t_step(self) -> float:
        """The time (s) of the last control step's end."""
        return self._t_step

    def aiding_counters(self) -> dict[str, int]:
        """What the estimators made of the aiding (none without): coarse observations due before the aid's first
        value (``<kind>_observations_awaiting_aid``, a wait) and after it without one (``…_unaided_observations``,
        a dropout), then the mode's own counts."""
        if not self.aid_width:
            return {}
        return {f"{self.aid_kind}_observations_awaiting_aid": self.coarse.observations_awaiting_aid,
                f"{self.aid_kind}_unaided_observations": self.coarse.unaided_observations, **self.mode.counters()}

    @property
    def awaiting_aid(self) -> bool:
        """An aided pipeline whose aid has not given its first value yet: the alignment has not started."""
        return bool(self.aid_width) and not self.coarse.aid_started

    def carry_aid_start(self, previous: AlignmentPipeline) -> None:
        """A fresh pipeline that replaces ``previous`` (a restart after an outage): an aid that had begun there stays
        begun here, so an observation without it is a dropout, not a wait."""
        self.coarse.carry_aid_start(previous.coarse)

    def stages_text(self) -> str:
        """The stages that run, for the operator's log (the mode's words)."""
        return self.mode.stages_text()

    def _epoch_counts(self, t: np.ndarray) -> np.ndarray:
        # the sample within half a period of k·P carries epoch k
        return np.floor((t + 0.5 * self.sample_period_s) / self.period_s).astype(np.int64)

    def process(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray,
                aid: np.ndarray | None = None, defer_control: bool = False) -> list[ResultRecord]:
        """Feed N samples (t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s, and for an aided pipeline the aiding at the
        samples, aid (N, Σ(1 + width) over :attr:`aid_kinds`): per kind the number of its newest epoch at or before
        the sample, then its values, NaN where none (:meth:`AidingTrack.aid_at`)); return the records they
        complete.

        ``defer_control``: when the samples end on a complete block, its noise measurement and control step (which
        no record of the block depends on) are left for :meth:`settle`, so the caller can publish the records
        first; the next call settles before anything else, so the results are the same bits either way."""
        self.settle()
        t = np.asarray(t, dtype=float).reshape(-1)
        if len(t) == 0:
            return []
        # only a call that ends on a complete block defers: its tail then refers to no sample the next one writes over
        self._defer_control = defer_control and (self._n_pending + len(t)) % self.block_samples == 0
        samples = None if self.aid_width else _imu_rows(t, dtheta, dv)
        if samples is None:
            columns = [t, np.reshape(dtheta, (-1, 3)), np.reshape(dv, (-1, 3))]
            if self.aid_width:
                columns.append(np.reshape(aid, (-1, self._pending.shape[1] - AID_COLUMN)))
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
        """Records whose epoch sample waits in the incomplete block: from the integrator run ahead over the pending
        samples when observing them would leave the coarse stage as it is, else on a scratch copy of it that
        integrates and observes them.

        The scan and the fold give a prefix of a block the same bits as the whole block, so these
        records equal what the complete block would emit; the block then skips them.
        """
        pending = self._pending[:self._n_pending]
        counts = self._epoch_counts(pending[:, 0])
        new = np.flatnonzero(stepped_up(counts, self._epoch_count) & (counts > self._emitted_count))
        if len(new) == 0:
            return
        if self.coarse.unchanged_until(float(pending[-1, 0])):   # no observation among them: no scratch copy needed
            q_b_b0 = self.coarse.integrator.ahead(pending[:, 1:4], pending[:, 4:7])
            for j in new.tolist():
                records.append(self._record(round(float(counts[j]) * self.period_s, 9), float(pending[j, 0]),
                                            q_b_b0[j], self.coarse))
            self._emitted_count = int(counts[new[-1]])
            return
        scratch = self.coarse.scratch()
        elapsed, q_b_b0, alpha = scratch.integrate(pending[:, 0], pending[:, 1:4], pending[:, 4:7])
        due, dK, trace_R = scratch.observe(elapsed, q_b_b0, alpha, *self._coarse_aid(self._aid(pending),
                                                                                    self._aid_epoch(pending)))
        folded = 0
        for j, upto in zip(new, np.searchsorted(due, new, side="right").tolist(), strict=True):
            folded = _fold_to(scratch.solver, dK, trace_R, folded, upto)
            records.append(self._record(round(float(counts[j]) * self.period_s, 9), float(pending[j, 0]), q_b_b0[j],
                                        scratch))
        self._emitted_count = int(counts[new[-1]])

    def settle(self) -> None:
        """Run the noise measurement and control step a call with ``defer_control`` left (none: nothing to do)."""
        if self._deferred is None:
            return
        (observed_s, observed_alpha), step = self._deferred
        self._deferred = None
        self._finish_block(observed_s, observed_alpha, *step)
        self._restarted = False   # after a chunk's last block: the new estimators start with the next samples

    def _finish_block(self, observed_s: np.ndarray, observed_alpha: np.ndarray, *step: object) -> None:
        """A block's tail after its records: the noise meter on its observations, then the control step."""
        if self.noise is not None:   # after the block's records: a record in an incomplete block sees the same
            self._measure_noise(observed_s, observed_alpha)
        self._control_step(*step)

    def _process_blocks(self, samples: np.ndarray, records: list[ResultRecord]) -> None:
        """Whole blocks (:meth:`_process_block_rows`); then their last Δθ is the one before the next sample's."""
        self.settle()
        self._process_block_rows(samples, records)
        self._dtheta_last = samples[-1, 1:4].copy()

    def _process_block_rows(self, samples: np.ndarray, records: list[ResultRecord]) -> None:
        """Whole blocks: integrate them at once, then per block fold the observations, emit, control."""
        M = self.block_samples
        t = samples[:, 0]
        elapsed, q_b_b0, alpha = self.coarse.integrate(t, samples[:, 1:4], samples[:, 4:7], M)
        aid, aid_epoch = self._aid(samples), self._aid_epoch(samples)
        due, dK, trace_R = self.coarse.observe(elapsed, q_b_b0, alpha, *self._coarse_aid(aid, aid_epoch))
        observed_s, observed_alpha = self.coarse.observed
        counts = self._epoch_counts(t)
        epochs = np.flatnonzero(stepped_up(counts, self._epoch_count))
        self._epoch_count = int(counts[-1])
        ends_array = np.arange(M - 1, len(t), M, dtype=np.intp)
        turn_blocks = self._watch_turns(t[ends_array], q_b_b0[ends_array])
        solver = self.coarse.solver
        # per block: the observations to fold by its end, and its epochs with those to fold by each (one search each
        # for the whole chunk, not per block)
        fold_end_array = np.searchsorted(due, ends_array, side="right").astype(np.intp)
        fold_epoch = np.searchsorted(due, epochs, side="right").tolist()
        # block b: its epochs epochs_by[b] to epochs_by[b + 1]
        epochs_by = [0, *np.searchsorted(epochs, ends_array, side="right").tolist()]
        blocks = self._blocks
        chunk = (ends_array, fold_end_array, t, elapsed, alpha, dK, trace_R, np.ascontiguousarray(observed_s),
                 np.ascontiguousarray(observed_alpha))
        if blocks is not None:   # the compiled loop's arrays as it reads them
            blocks.chunk(*chunk)
            # each run stops at the next block with epochs (their records are Python's), a turn's (its control step
            # changes the stages) or a deferred last block
            # (a set, not np.union1d: its first call imports numpy.ma, 14 ms at the live path's first control step)
            limits = sorted({*np.searchsorted(ends_array, epochs).tolist(), *turn_blocks.tolist()})
            limits.append(len(ends_array) - 1 if self._defer_control else len(ends_array))
        ends, fold_end, folded, b = ends_array.tolist(), fold_end_array.tolist(), 0, 0
        while b < len(ends):
            measured = folded   # the block's observations, whether an epoch's record folded some of them already
            for e in range(epochs_by[b], epochs_by[b + 1]):
                j = epochs[e]
                folded = _fold_to(solver, dK, trace_R, folded, fold_epoch[e])
                if counts[j] > self._emitted_count:
                    records.append(self._record(round(float(counts[j]) * self.period_s, 9), float(t[j]), q_b_b0[j],
                                                self.coarse))
                    self._emitted_count = int(counts[j])
            stage = CONTRADICTED if self._contradiction is not None else UNTOUCHED
            if blocks is not None and stage == UNTOUCHED:
                limit = limits[min(bisect_right(limits, b), len(limits) - 1)]
                resume = False
                while limit > b and self._blocks_ready():
                    handover = (self.mode.handover_terms() if self.fine is not None and not self.fine.active
                                else None)
                    b, stage, folded, self._alpha_step, self._t_step, self._next_check_s = blocks.run(
                        b, limit, folded, measured, resume, self._alpha_step, self._t_step, self._next_check_s,
                        handover)
                    if stage != VERDICT:
                        break
                    self._take_verdict()   # then the block's control step, compiled again
                    stage, resume, measured = CONTROL, True, folded
                if stage == DONE:
                    continue
            end = ends[b]
            step = (float(t[end]), float(elapsed[end]), q_b_b0[end], alpha[end], None if aid is None else aid[end],
                    None if aid_epoch is None else aid_epoch[end])
            if stage == CONTRADICTED:   # an estimate of this block's records contradicts the earlier ones
                self._restart_contradicted(step[0])
            elif stage == CONTROL:   # the compiled loop folded and measured the block
                self._control_step(*step)
            elif stage == MOTION:   # … and took its control step but for the motion check
                self._check_motion(step[0], step[1], step[3])
            else:
                folded = _fold_to(solver, dK, trace_R, folded, fold_end[b])
                observed = observed_s[measured:folded], observed_alpha[measured:folded]
                if self._defer_control and end + 1 == len(t):
                    self._deferred = observed, step   # the chunk's last block: its records leave first
                    return
                self._finish_block(*observed, *step)
            if self._restarted:   # new estimators: they integrate the rest of the chunk themselves
                self._restarted = False
                if end + 1 < len(t):
                    self._process_blocks(samples[end + 1:], records)
                return
            if self._blocks is not blocks:   # a turn changed the fine stage: its compiled loop takes the chunk on
                blocks = self._blocks
                if blocks is not None:
                    blocks.chunk(*chunk)
            b += 1

    def _blocks_ready(self) -> bool:
        """Whether the compiled loop can take the next blocks: no stored-data passes under way, the base not known
        to move, and no hand-over after a turn due (the mode seeds those loops with what the turn left)."""
        fine = self.fine
        return ((fine is None or (fine.passes is None and (fine.passes_done or not fine.buffer.full)
                                  and (fine.active or self.turns is None or not self.turns.turned)))
                and (self.motion is None or self.motion.episode is None))

    def _measure_noise(self, elapsed_s: np.ndarray, alpha: np.ndarray) -> None:
        """Feed one block's observations (elapsed (M,) s, α (M, 3) m/s) to the noise meter; every
        :data:`VERDICT_STEPS` observations σ takes the figures the data show (service/align/noise_check.py), and the
        operator is told once of a datasheet far too quiet."""
        if self.noise.feed(elapsed_s, alpha):
            self._take_verdict()

    def _take_verdict(self) -> None:
        """The noise meter's verdict, due every :data:`VERDICT_STEPS` observations."""
        coarse = self.coarse
        heading_sigma_rad = None
        if coarse.solver.n_obs:
            self.noise.C_n0_b0 = dcm_from_quat(coarse.q_b_n0).T
            heading_sigma_rad = lambda: coarse.sigma(coarse.t - coarse.t0)[0] * DEG   # noqa: E731 (asked rarely)
        verdict = self.noise.verdict(self.grade, heading_sigma_rad)
        self.noise_unchecked = self.noise_unchecked and verdict is None
        if verdict is not None and verdict.grade != self.sigma_grade:
            self.sigma_grade = verdict.grade
            self._apply_sigma_grade()
            self.last_notice = self.last_notice or verdict.notice

    def _apply_sigma_grade(self) -> None:
        """The stages report σ with :attr:`sigma_grade` (their estimates keep the datasheet's weights and gains). The
        loops take it until they start: their covariance then runs on with one grade, so live passes sliced over
        many steps propagate it as offline passes run at once do."""
        self.coarse.report_with(self.sigma_grade)
        if isinstance(self.fine, FineAlignment):
            self.fine.report_with(self.sigma_grade)
        # estimates move with the noise, not with a bias (its effect all but constant): the consistency check takes σ
        # with the datasheet's bias, whatever bias the data show (a lost slice of rotation shows as one at first)
        bias = self.grade.gyro_bias_rad_s
        self._moving_grade = (self.sigma_grade if self.sigma_grade.gyro_bias_rad_s == bias
                              else replace(self.sigma_grade, gyro_bias_rad_s=bias))

    def _aid(self, samples: np.ndarray) -> np.ndarray | None:
        """The aiding values of the samples (N, ``aid_width``: every kind's, in order), None without aiding; with the
        mode's ``gyro_rate`` the gyro rate ω_ib^b (3, rad/s) appended, from the increments
        (1.5 Δθ_k − 0.5 Δθ_{k−1}) / T: the rate at the sample's end, second-order accurate (lever arms, rotation
        pairs)."""
        if not self.aid_width:
            return None
        aid = (samples[:, AID_COLUMN + 1:] if len(self.mode.aids) == 1 else samples[:, self._value_columns])
        if not self.mode.gyro_rate:
            return aid
        dtheta = samples[:, 1:4]
        previous = np.concatenate((self._dtheta_last[None], dtheta[:-1]))
        return np.hstack((aid, (1.5 * dtheta - 0.5 * previous) / self.sample_period_s))

    def _aid_epoch(self, samples: np.ndarray) -> np.ndarray | None:
        """The number (N, kinds) of each kind's newest aiding epoch at or before each sample (NaN: none), None
        without aiding."""
        return samples[:, self._epoch_columns] if self.aid_width else None

    def _coarse_aid(self, aid: np.ndarray | None, aid_epoch: np.ndarray | None
                    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """What the coarse stage observes of the aiding: every value (with the gyro rate), and the epoch numbers of
        its kind (one observation per epoch of that kind)."""
        return aid, None if aid_epoch is None else aid_epoch[:, self._coarse_index]

    def _control_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, alpha: np.ndarray,
                      aid: np.ndarray | None, aid_epoch: np.ndarray | None) -> None:
        dalpha, dt_s = alpha - self._alpha_step, t_end - self._t_step
        self._alpha_step, self._t_step = alpha, t_end
        if aid_epoch is None:
            fresh = _NONE_FRESH
        else:   # one Kalman update per aiding epoch: a slower aid interpolated over several steps is one measurement
            fresh = aid_epoch > self._step_epoch
            self._step_epoch = np.where(fresh, aid_epoch, self._step_epoch)
        self.mode.step(t_end, elapsed_s, q_b_b0, dalpha, dt_s, aid, fresh)
        while self._turn_events and self._turn_events[0][0] <= t_end:
            self._turn(t_end, self._turn_events.pop(0)[1])
        if self.motion is not None and elapsed_s >= self._next_check_s:
            self._next_check_s = elapsed_s + self.config.disturbance.check_interval_s
            self._check_motion(t_end, elapsed_s, alpha)

    def _watch_turns(self, t_end: np.ndarray, q_b_b0: np.ndarray) -> np.ndarray:
        """The turn watch over a chunk's control steps (their end times (K,) s and body attitudes (K, 4)): its
        events wait for their control steps; the indices of those steps (the compiled loop leaves them to Python)."""
        if self.turns is None:
            return np.zeros(0, np.intp)
        events = self.turns.scan(t_end, q_b_b0)
        self._turn_events += [(float(t_end[k]), event) for k, event in events]
        return np.array([k for k, _ in events], np.intp)

    def _turn(self, t_end: float, event: int) -> None:
        """A turn (the compass loops dropped: they hold the biases as they were in n) or a base steady again after
        one (fresh loops, handed over from the coarse stage as at the start, their stored data all after it)."""
        if event == TURNED:
            self.fine = None
            self.last_disturbance = (f"base turning at t = {t_end:.2f} s: the compass loops wait until it is steady, "
                                     "the coarse stage carries the attitude")
        else:
            self.fine = self.mode.make_fine()
            self.last_disturbance = f"base steady again at t = {t_end:.2f} s: the compass loops start afresh"
        self._blocks = fixed_base_blocks(self)

    def _check_motion(self, t_end: float, elapsed_s: float, alpha: np.ndarray) -> None:
        """Watch for a base that translates (:class:`MotionMonitor`) under the coarse estimate, which runs through
        every stage: while it moves the records are ``disturbed`` with the trusted attitude carried on by the gyros;
        once it is at rest again the alignment restarts if the data contradict it (``action = "restart"``)."""
        if self.coarse.solver.n_obs == 0:
            return
        found = self.motion.check(elapsed_s, alpha, dcm_from_quat(self.coarse.q_b_n0),
                                  lambda at_s: tuple(sigma_deg * DEG for sigma_deg in self.coarse.sigma(at_s)))
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

    def _restart_contradicted(self, t_end: float) -> None:
        """Start the alignment over after the data contradicted its estimates (:mod:`~.align.consistency`)."""
        self.disturbances += 1
        self.last_disturbance = f"at t = {t_end:.2f} s {self._contradiction}: alignment restarted"
        self._contradiction = None
        self._start_estimators(t_end)

    def _record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
                coarse: InertialCoarseAlignment) -> ResultRecord:
        episode = None if self.motion is None else self.motion.episode
        if episode is not None:
            # a base that moves: the attitude trusted before the motion, carried on by the gyros, its σ with their drift
            elapsed = t_sample - coarse.t0
            C_b_n = coarse.source.C_n_n0(elapsed).T @ episode.C_b0_n0 @ dcm_from_quat(q_b_b0)
            sigma = carried_sigma(AttitudeSigma(episode.heading_sigma_rad / DEG, episode.level_sigma_rad / DEG),
                                  coarse.sigma_grade, elapsed - episode.start_s)
            solution = AttitudeSolution(t_sample, quat_from_dcm(C_b_n), sigma.heading_deg, sigma.level_deg,
                                        coarse.solver.rho, coarse.solver.trace_P, coarse.solver.n_obs)
            record = result_record(solution, t_epoch, "disturbed", self.config.alignment.converged_heading_sigma_deg)
        else:
            record = self.mode.record(t_epoch, t_sample, q_b_b0, coarse)
        if episode is not None or t_sample < self._disturbed_until:
            # nothing converged survives a disturbance until the restarted alignment earns it again
            return replace(record, phase="disturbed", converged=False)
        suspect = self.motion is not None and self.motion.suspect   # a base that may be starting to move
        # σ rests on the datasheet alone until the data's noise has checked it: a datasheet that claims no noise gave
        # σ 0.06° at 1 s on a heading 173° off
        trusted = record.converged and not suspect and not self.noise_unchecked
        consistency = self.consistency
        if consistency is not None and self._contradiction is None and coarse.t0 is not None \
                and t_sample - coarse.t0 >= consistency.next_s:
            elapsed_s, grade, (lat, gravity) = t_sample - coarse.t0, self._moving_grade, self._lat_gravity
            sigma = inertial_alignment_sigma(grade, lat, gravity, elapsed_s)
            self._contradiction = consistency.check(elapsed_s, coarse.q_b_n0,
                                                    math.hypot(sigma.heading_deg, sigma.level_deg),
                                                    partial(inertial_alignment_sigmas, grade, lat, gravity),
                                                    keep=trusted)
        if record.converged and (not trusted or self._contradiction is not None):
            return replace(record, converged=False)   # a contradiction restarts the alignment at its block's end
        return record


def build_pipeline(config: Config, site: Site, rate_hz: float, datasheet: dict[str, float] | None = None,
                   aids: Iterable[str] = (), live: bool = False) -> AlignmentPipeline:
    """The pipeline of the mode the aiding kinds ``aids`` select (:data:`~service.modes.MODES`). What an aiding log
    states of its sensor (noise, lever arm) belongs in ``config.aiding`` (the replay puts it there)."""
    kinds = frozenset(aids)
    if kinds not in MODES:
        known = ", ".join(sorted("+".join(sorted(k)) or "(none)" for k in MODES))
        raise ConfigError(f"aids {', '.join(sorted(kinds))}: no aided mode for this combination yet (known: {known})")
    return AlignmentPipeline(config, site, rate_hz, datasheet, live, mode=MODES[kinds])
