"""What the aided pipelines whose fine stage is the error-state Kalman filter share: its records.

The odometer (service/aided_pipeline.py) and GNSS (service/gnss_pipeline.py) pipelines hand over
from their coarse stage to :class:`~service.align.kalman.ErrorStateFilter`; from then on the
attitude and its σ come from the filter, and ``aligned`` means its heading σ is at or below
``alignment.converged_heading_sigma_deg``.
"""
from __future__ import annotations

import numpy as np

from ..protocol.results import ResultRecord
from .align.coarse import AttitudeSolution, InertialCoarseAlignment
from .align.conventions import dcm_from_quat, quat_from_dcm
from .align.kalman import ErrorStateFilter
from .pipeline import AlignmentPipeline, result_record


class KalmanStagePipeline(AlignmentPipeline):
    """An :class:`AlignmentPipeline` whose fine stage is an :class:`ErrorStateFilter`."""

    fine: ErrorStateFilter | None
    checks_noise = False
    sigma_margin = 1.25
    """The reported σ is the filter's times this. The filters are Gaussian-calibrated (seed 002, 20 seeds from
    10 s: |error|/σ median 0.71, p99 2.3-2.5; seed 004, 40 seeds, 30-120 s, GNSS at 50/10/5/1 Hz: median 0.52-0.63,
    p99 2.3-2.55, max 2.84-3.07), and so they reach 3σ about once in a few thousand epochs. "Never converged beyond
    3σ" asks for a margin: 1.25 puts those tails at 2.3-2.5σ (docs/algorithms/transfer.md, "σ, as calibrated";
    docs/algorithms/gnss.md, "Slower receivers")."""

    def _measurements(self, aid: np.ndarray) -> list[tuple[str, np.ndarray]]:
        """(measurement name, value) of one control step's aiding values (finite)."""
        raise NotImplementedError

    def _kalman_step(self, dalpha: np.ndarray, dt_s: float, C_b_b0: np.ndarray, aid: np.ndarray | None,
                     fresh: bool) -> bool:
        """Once the filter runs: predict over the control step (Δα (3,) m/s in b0 axes, ``dt_s``, ending at body
        attitude C_b^{b0}) and fold the step's measurements if its aiding is there and ``fresh`` (an epoch the
        filter has not had: the same two epochs interpolated again are not a new measurement). False before the
        filter runs."""
        if self.fine is None or not self.fine.active:
            return False
        self.fine.predict(dalpha, dt_s, C_b_b0)
        if fresh and aid is not None and np.isfinite(aid).all():
            for name, value in self._measurements(aid):
                self.fine.update(name, value)
        return True

    handover_limit_key = "handover_heading_sigma_deg"
    """The ``[aiding]`` key of the largest coarse heading σ (deg) the Kalman stage starts from."""

    def _handover_solution(self, t_end: float, q_b_b0: np.ndarray, notice: tuple[str, str] | None
                           ) -> AttitudeSolution | None:
        """The coarse solution at the step's end to start the filter from, or None while its heading σ is above
        ``aiding.<handover_limit_key>``: a linear filter started several degrees off turns overconfident
        (seed 003 at 20 m/s: a 4°-σ window left 3-5° errors at σ 0.3°). ``notice`` (what comes before and after
        "heading σ … > …") tells the operator once why the coarse stage goes on; None: nothing to tell."""
        solution = self.coarse.solution_at(t_end, q_b_b0)
        limit = getattr(self.config.aiding, self.handover_limit_key)
        if solution.heading_sigma_deg <= limit:
            return solution
        if notice is not None:
            self.last_notice = self.last_notice or (f"{notice[0]}heading σ {solution.heading_sigma_deg:.2f}° > "
                                                    f"aiding.{self.handover_limit_key} {limit:g}°{notice[1]}")
        return None

    def aiding_counters(self) -> dict[str, int]:
        """The coarse stage's (:meth:`AlignmentPipeline.aiding_counters`), then each measurement's updates the filter
        accepted and its gate turned away (``<name>_accepted``, ``<name>_rejected``; none before the filter exists)."""
        filter_counts = {} if self.fine is None else {f"{name}_{what}": getattr(c, what)
                                                       for name, c in self.fine.counters.items()
                                                       for what in ("accepted", "rejected")}
        return {**super().aiding_counters(), **filter_counts}

    def _stage_record(self, t_epoch: float, t_sample: float, q_b_b0, coarse: InertialCoarseAlignment) -> ResultRecord:
        if self.fine is None or not self.fine.active:
            return super()._stage_record(t_epoch, t_sample, q_b_b0, coarse)
        threshold = self.config.alignment.converged_heading_sigma_deg
        sigma = self.fine.sigma
        C_b_n = self.fine.attitude(dcm_from_quat(q_b_b0), t_sample - self._t_step)
        m = self.sigma_margin
        solution = AttitudeSolution(t_sample, quat_from_dcm(C_b_n), m * sigma.heading_deg, m * sigma.level_deg,
                                    coarse.solver.rho, coarse.solver.trace_P, coarse.solver.n_obs)
        aligned = solution.heading_sigma_deg <= threshold
        return result_record(solution, t_epoch, "aligned" if aligned else "fine", threshold)


class GyroRateAidPipeline(KalmanStagePipeline):
    """A Kalman-stage pipeline whose aid columns get the gyro rate ω_ib^b (3, rad/s) appended, from the
    increments (1.5 Δθ_k − 0.5 Δθ_{k−1}) / T: the rate at the sample's end, second-order accurate (lever
    arms, rotation pairs)."""

    def __init__(self, *args, **kwargs) -> None:
        self._dtheta_last = np.zeros(3)
        super().__init__(*args, **kwargs)

    def _aid(self, samples: np.ndarray) -> np.ndarray:
        dtheta = samples[:, 1:4]
        previous = np.concatenate((self._dtheta_last[None], dtheta[:-1]))
        rates = (1.5 * dtheta - 0.5 * previous) / self.sample_period_s
        return np.hstack((super()._aid(samples), rates))

    def _process_blocks(self, samples: np.ndarray, records: list) -> None:
        super()._process_blocks(samples, records)
        self._dtheta_last = samples[-1, 1:4].copy()
