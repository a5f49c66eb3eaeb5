"""The pinned result record of an attitude solution or of a record's angles."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..protocol.results import ResultRecord
from .align._attitude import record_angles
from .align.coarse import AttitudeSolution


def result_record(solution: AttitudeSolution, t_epoch: float, phase: str, threshold_deg: float) -> ResultRecord:
    """The pinned result of one solution, stamped with its output epoch."""
    return record_of(record_angles(np.ascontiguousarray(solution.q_b_n, dtype=float)), t_epoch, phase,
                     solution.heading_sigma_deg, solution.level_sigma_deg, threshold_deg, solution.rho,
                     solution.trace_P, solution.n_obs)


def record_of(angles: tuple, t_epoch: float, phase: str, heading_sigma_deg: float, level_sigma_deg: float,
              threshold_deg: float, rho: float, trace_P: float, n_obs: int) -> ResultRecord:
    """The pinned result of an attitude's angles (``_attitude.record_angles``: the unit quaternion, heading, pitch and
    roll in degrees) with its σ and the solver's figures, ``converged`` at or below the threshold."""
    q, heading_deg, pitch_deg, roll_deg = angles
    return ResultRecord(t=t_epoch, phase=phase, q=q, pitch_deg=pitch_deg, roll_deg=roll_deg, heading_deg=heading_deg,
                        heading_sigma_deg=heading_sigma_deg, level_sigma_deg=level_sigma_deg,
                        converged=bool(heading_sigma_deg <= threshold_deg), rho=float(rho), trace_P=float(trace_P),
                        n_obs=n_obs)


def coarse_record(solution: AttitudeSolution, t_epoch: float, threshold_deg: float, has_fine: bool) -> ResultRecord:
    """The record of the coarse stage's solution before a fine stage runs; without a fine stage at all, a converged
    coarse solution is the end of the alignment (``aligned``)."""
    record = result_record(solution, t_epoch, "coarse", threshold_deg)
    return replace(record, phase="aligned") if not has_fine and record.converged else record
