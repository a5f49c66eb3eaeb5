"""The pinned result record of an attitude solution, and the output rule once a fine stage runs beside the coarse
one."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..protocol.results import ResultRecord
from .align._attitude import output_quaternion, record_angles
from .align.coarse import AttitudeSolution


def result_record(solution: AttitudeSolution, t_epoch: float, phase: str, threshold_deg: float) -> ResultRecord:
    """The pinned result of one solution, stamped with its output epoch."""
    q, heading_deg, pitch_deg, roll_deg = record_angles(np.ascontiguousarray(solution.q_b_n, dtype=float))
    return ResultRecord(t=t_epoch, phase=phase, q=q, pitch_deg=pitch_deg, roll_deg=roll_deg, heading_deg=heading_deg,
                        heading_sigma_deg=solution.heading_sigma_deg, level_sigma_deg=solution.level_sigma_deg,
                        converged=bool(solution.heading_sigma_deg <= threshold_deg), rho=float(solution.rho),
                        trace_P=float(solution.trace_P), n_obs=solution.n_obs)


def smaller_sigma_solution(coarse: AttitudeSolution, C_fine: np.ndarray, fine_heading_sigma_deg: float,
                           fine_level_sigma_deg: float) -> AttitudeSolution:
    """The output once the loops run beside the coarse stage (which runs on): the level of whichever of the two
    claims the smaller level σ, the heading of whichever claims the smaller heading σ, each with its σ. So the fine
    stage never makes either worse than the coarse stage alone would give (a 600-s least-squares heading can beat a
    narrow loop, while the loops hold the level that the inertial-frame fit lets drift by ε·T). The attitude is
    compiled (``_attitude.output_quaternion``: quat_from_dcm of the one, or of conventions.with_heading_of)."""
    q_b_n = output_quaternion(np.ascontiguousarray(coarse.q_b_n, dtype=float), coarse.heading_sigma_deg,
                              coarse.level_sigma_deg, C_fine, fine_heading_sigma_deg, fine_level_sigma_deg)
    if q_b_n is None:
        return coarse
    return AttitudeSolution(coarse.t, q_b_n, min(fine_heading_sigma_deg, coarse.heading_sigma_deg),
                            min(fine_level_sigma_deg, coarse.level_sigma_deg), coarse.rho, coarse.trace_P,
                            coarse.n_obs)


def coarse_record(solution: AttitudeSolution, t_epoch: float, threshold_deg: float, has_fine: bool) -> ResultRecord:
    """The record of the coarse stage's solution before a fine stage runs; without a fine stage at all, a converged
    coarse solution is the end of the alignment (``aligned``)."""
    record = result_record(solution, t_epoch, "coarse", threshold_deg)
    return replace(record, phase="aligned") if not has_fine and record.converged else record
