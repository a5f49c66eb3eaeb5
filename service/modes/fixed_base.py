"""Fixed base (seeds 000 and 001): the inertial-frame coarse stage on the Earth's rotation, then the compass loops.

Observation source: the fixed site (gravity turning with the Earth). Solver: ``alignment.solver`` (OPREQ, GLS …, or
the one "auto" picks for the datasheet). σ: the coarse stage's model, with the noise the data show. Fine stage: the
compass loops with their gain schedule and stored-data passes, from the step at which the coarse heading σ (its
noise part) is within ``fine.compass.handover_sigma_deg`` (or at ``fine.compass.handover_time_s``). The output
takes level and heading each from whichever stage claims the smaller σ. A turn of the base drops the loops until it
is steady again (``watches_turns``): the coarse stage alone carries the attitude through it.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ...protocol.results import ResultRecord
from ..align._blocks import handover_due, noise_part
from ..align.coarse import AttitudeSolution, InertialCoarseAlignment
from ..align.compass import GainSchedule
from ..align.conventions import DEG, dcm_from_quat, quat_from_dcm
from ..align.fine import FineAlignment
from ..align.observations import FixedSiteSource
from ..align.sensor_model import ESTIMATOR_EFFICIENCY, SIGMA_UNKNOWN_DEG, bias_limit_rad, coarse_sigma_terms
from ..align.solvers import make_solver
from ..align.swing_bias import SwingBias
from ..align.turning_bias import TurningBiasTerm
from ..records import coarse_record, record_of, result_record

if TYPE_CHECKING:
    from ..pipeline import AlignmentPipeline

INITIAL_TILT_SIGMA_DEG = 0.1
INITIAL_HEADING_SIGMA_DEG = 1.5
"""1-sigma errors assumed for an attitude given from outside (compass alone, seed 001's start)."""


class FixedBase:
    """The fixed-base mode of ``pipeline`` (its configuration, grade, site and estimators)."""

    aids: tuple[tuple[str, int], ...] = ()
    coarse_kind = ""
    checks_translation = True
    checks_noise = True
    watches_turns = True
    """The compass loops hold the biases as they were in n: on a turn the pipeline drops them until the base is
    steady (service/align/turns.py), the coarse stage carrying the attitude."""
    gyro_rate = False

    def __init__(self, pipeline: AlignmentPipeline) -> None:
        self.p = pipeline

    def make_coarse(self) -> InertialCoarseAlignment:
        p, a = self.p, self.p.config.alignment
        solver = make_solver(p.solver_name, a.request_rho, p.grade, p.site.gravity, a.disturbance_velocity_mps)
        swing_bias = SwingBias(p.site.lat, p.grade.acc_bias_ms2, p.grade.acc_vrw_ms_rts) if a.swing_bias else None
        return InertialCoarseAlignment(FixedSiteSource(p.site), p.grade, solver, p.sample_period_s,
                                       a.obs_interval_s, a.disturbance_velocity_mps, swing_bias,
                                       TurningBiasTerm(p.site.lat, p.site.gravity))

    def make_fine(self) -> FineAlignment | None:
        p = self.p
        if not p.with_fine:
            return None
        f = p.config.fine.compass
        return FineAlignment(p.site, p.grade, GainSchedule(f.schedule_time_s, f.level_sigma, f.azimuth_sigma),
                             p.block_samples * p.sample_period_s, f.stored_data_s, f.stored_pairs,
                             f.live_pass_steps if p.live else None)

    def stages_text(self) -> str:
        """The coarse solver ("auto" says what it chose), the swing-bias fit and the compass stage."""
        p, a = self.p, self.p.config.alignment
        solver = p.solver_name
        if a.solver == "auto":
            solver += f" (auto: {'gyro walk' if solver == 'gls' else 'accelerometer noise'} dominates)"
        return (f"coarse solver {solver}, swing-bias fit {'on' if a.swing_bias else 'off'}, "
                f"compass stage {'on' if p.with_fine else 'off'}")

    def counters(self) -> dict[str, int]:
        return {}

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """One control step: the loops take Δα (3,) m/s over ``dt_s`` ending at ``t_end``; before they run, the
        hand-over from the coarse stage."""
        p = self.p
        if p.fine is None:
            return
        if not p.fine.active and p.initial_C_b_n is not None:
            p.fine.start(p.initial_C_b_n, np.eye(3), INITIAL_TILT_SIGMA_DEG * DEG, INITIAL_HEADING_SIGMA_DEG * DEG)
        p.fine.feed(dalpha, dt_s)
        if not p.fine.active and self._handover_due(elapsed_s):
            solution = p.coarse.solution_at(t_end, q_b_b0)
            tilt, heading = self._noise_part(solution.heading_sigma_deg, solution.level_sigma_deg)
            if p.turns is not None and p.turns.turned:
                # the coarse fit spans attitudes before and after a turn, which average the biases; the loops settle
                # where this attitude's biases put them: the two differ by up to twice the bias limit, which the
                # loops' start must hold (seeded with the noise alone, they were 3σ off 8 s after an index)
                grade, site = p.coarse.grade, p.coarse.source.site
                bias_heading, bias_level = bias_limit_rad(grade, site.lat, site.gravity)
                tilt, heading = float(np.hypot(tilt, 2.0 * bias_level)), float(np.hypot(heading, 2.0 * bias_heading))
            p.fine.start(dcm_from_quat(solution.q_b_n), dcm_from_quat(q_b_b0), tilt, heading,
                         t_loop_s=p.config.fine.compass.handover_schedule_s)

    def _handover_due(self, elapsed_s: float) -> bool:
        """The hand-over to the compass loops (``_policy.pxi``, the rule the compiled loop applies): at the configured
        time, or once the noise part of the coarse heading σ is within the threshold. The noise part only: the bias
        floor stays whatever the stage, and above the threshold for a poor gyro it would keep the loops from ever
        starting; but a heading at the unknown angle's σ has no noise part to speak of (a bias limit beyond the cap
        would leave 0 of it, and a 200°/h gyro's loops would start with no heading uncertainty at 10 s, their levels
        7° off under σ 0.13°). Not before a least time, nor before the data's noise has checked σ: a datasheet that
        claims far too little noise would hand over at the first observation, and the loops carry σ on."""
        f = self.p.config.fine.compass
        return handover_due(f.handover == "time", f.handover_time_s, f.handover_min_s, f.handover_sigma_deg,
                            SIGMA_UNKNOWN_DEG, ESTIMATOR_EFFICIENCY, elapsed_s, self.p.coarse.solver.n_obs,
                            self.handover_terms())

    def handover_terms(self) -> tuple[float, ...]:
        """What the hand-over test (``_policy.pxi``, in the compiled loop and the Python steps alike) needs: the coarse
        σ model's terms of the grade σ takes (sensor_model.coarse_sigma_terms), the datasheet's heading bias limit
        (rad) and whether the data's noise has yet to check σ."""
        p = self.p
        coarse = p.coarse
        terms = coarse_sigma_terms(coarse.sigma_grade, coarse.source.site.lat, coarse.source.site.gravity)
        bias_heading, _ = bias_limit_rad(coarse.grade, coarse.source.site.lat, coarse.source.site.gravity)
        return (*terms, bias_heading, p.noise_unchecked)

    def _noise_part(self, heading_sigma_deg: float, level_sigma_deg: float) -> tuple[float, float]:
        """1-sigma (tilt, heading) noise errors (rad) of a coarse solution: its σ without the bias limit, divided by
        the efficiency factor the reported σ carries, to seed the loops' covariance (``_policy.pxi``)."""
        grade, site = self.p.coarse.grade, self.p.coarse.source.site
        bias_heading, bias_level = bias_limit_rad(grade, site.lat, site.gravity)
        return (noise_part(level_sigma_deg, bias_level, ESTIMATOR_EFFICIENCY),
                noise_part(heading_sigma_deg, bias_heading, ESTIMATOR_EFFICIENCY))

    def record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
               coarse: InertialCoarseAlignment) -> ResultRecord:
        """The record of an output epoch: the coarse solution alone until the loops run, then the output rule: the
        level of whichever of the two claims the smaller level σ, the heading of whichever claims the smaller heading
        σ, each with its σ. So the fine stage never makes either worse than the coarse stage alone would give (a
        600-s least-squares heading can beat a narrow loop, while the loops hold the level that the inertial-frame
        fit lets drift by ε·T); the attitudes and the rule are compiled (``_attitude.fine_record_angles``)."""
        p = self.p
        threshold = p.config.alignment.converged_heading_sigma_deg
        if p.fine is None or not p.fine.active:
            # loops dropped on a turn come back: the coarse stage's answer is not the end of the alignment
            return coarse_record(coarse.solution_at(t_sample, q_b_b0), t_epoch, threshold, p.with_fine)
        if p.initial_C_b_n is not None:
            # a compass-alone start from a given attitude (evaluation) is the loops' alone
            sigma = p.fine.sigma
            C_fine = p.fine.attitude(dcm_from_quat(q_b_b0), t_sample - p.t_step)
            solution = AttitudeSolution(t_sample, quat_from_dcm(C_fine), sigma.heading_deg, sigma.level_deg,
                                        coarse.solver.rho, coarse.solver.trace_P, coarse.solver.n_obs)
            return result_record(solution, t_epoch, self._fine_phase(solution.heading_sigma_deg, threshold),
                                 threshold)
        elapsed = t_sample - coarse.t0
        coarse_sigma = coarse.sigma(elapsed)
        angles, fine_sigma = p.fine.record_angles(coarse.source.site.lat, elapsed, coarse.q_b_n0, q_b_b0,
                                                  coarse_sigma, t_sample - p.t_step)
        heading_sigma, level_sigma = min(fine_sigma[0], coarse_sigma[0]), min(fine_sigma[1], coarse_sigma[1])
        solver = coarse.solver
        return record_of(angles, t_epoch, self._fine_phase(heading_sigma, threshold), heading_sigma, level_sigma,
                         threshold, solver.rho, solver.trace_P, solver.n_obs)

    def _fine_phase(self, heading_sigma_deg: float, threshold_deg: float) -> str:
        """``aligned`` once the loops' schedule is complete and the heading σ within the threshold, else ``fine``."""
        return "aligned" if self.p.fine.schedule_complete and heading_sigma_deg <= threshold_deg else "fine"


MODE = FixedBase
"""The mode this module declares (:data:`~service.modes.MODES`)."""
