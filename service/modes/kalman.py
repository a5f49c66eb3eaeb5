"""What the modes whose fine stage is the error-state Kalman filter share (odometer, GNSS, master INS).

Each such mode subclasses :class:`KalmanMode` and declares its coarse stage, its filter's measurements and its
hand-over; from the hand-over on the attitude and its σ come from the filter, and ``aligned`` means its heading σ
is at or below ``alignment.converged_heading_sigma_deg``.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ...protocol.results import ResultRecord
from ..align.coarse import AttitudeSolution, InertialCoarseAlignment
from ..align.conventions import dcm_from_quat, quat_from_dcm
from ..align.datasheet_bank import DatasheetBank
from ..align.kalman import ErrorStateFilter, Measurement
from ..align.sensor_model import SIGMA_UNKNOWN_DEG
from ..records import coarse_record, result_record

if TYPE_CHECKING:
    from ..pipeline import AlignmentPipeline


class KalmanMode:
    """The shared part of a Kalman-stage mode of ``pipeline``; a subclass gives ``aids``, ``coarse_kind``,
    :meth:`make_coarse`, :meth:`make_fine`, :meth:`measurements` and :meth:`step` (its hand-over)."""

    aids: tuple[tuple[str, int], ...] = ()
    coarse_kind = ""
    checks_translation = False
    checks_noise = False
    watches_turns = False   # the filter holds the biases in body axes: a turn makes them observable, not wrong
    gyro_rate = False
    sigma_margin = 1.25
    """The reported σ is the filter's times this. The filters are Gaussian-calibrated (seed 002, 20 seeds from
    10 s: |error|/σ median 0.71, p99 2.3-2.5; seed 004, 40 seeds, 30-120 s, GNSS at 50/10/5/1 Hz: median 0.52-0.63,
    p99 2.3-2.55, max 2.84-3.07), and so they reach 3σ about once in a few thousand epochs. "Never converged beyond
    3σ" asks for a margin: 1.25 puts those tails at 2.3-2.5σ (docs/algorithms/transfer.md, "σ, as calibrated";
    docs/algorithms/gnss.md, "Slower receivers")."""
    handover_limit_key = "fine.kalman.handover_heading_sigma_deg"
    """The configuration key (dotted) of the largest coarse heading σ (deg) the Kalman stage starts from."""

    def __init__(self, pipeline: AlignmentPipeline) -> None:
        self.p = pipeline
        self._kind_index = {kind: i for i, (kind, _) in enumerate(self.aids)}   # each kind's column in ``fresh``

    def make_coarse(self) -> InertialCoarseAlignment:
        raise NotImplementedError

    def make_fine(self) -> DatasheetBank | None:
        raise NotImplementedError

    def filter_bank(self, measurements: Callable[[], list[Measurement]]) -> DatasheetBank | None:
        """The Kalman stage of this mode: a datasheet bank of error-state filters on the pipeline's grade, each with
        its own ``measurements()`` and the configured gate; None if the fine stage is off."""
        p = self.p
        if not p.config.fine.enabled:
            return None
        gate_chi2 = p.config.fine.kalman.gate_chi2
        return DatasheetBank(lambda grade: ErrorStateFilter(grade, measurements(), gate_chi2), p.grade)

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """(aiding kind, measurement name, value) of one control step's aiding values (NaN where the kind has
        none)."""
        raise NotImplementedError

    def aids_text(self) -> str:
        """The aiding kinds, as the operator reads them ("odo and gnss")."""
        return " and ".join(kind for kind, _ in self.aids)

    def stages_text(self) -> str:
        return f"{'+'.join(kind for kind, _ in self.aids)}-aided alignment"

    def kalman_step(self, dalpha: np.ndarray, dt_s: float, C_b_b0: np.ndarray, aid: np.ndarray | None,
                    fresh: np.ndarray) -> bool:
        """Once the filter runs, :meth:`fold` the control step into it. False before the filter runs."""
        fine = self.p.fine
        if fine is None or not fine.active:
            return False
        self.fold(fine, dalpha, dt_s, C_b_b0, aid, fresh)
        return True

    def fold(self, fine: DatasheetBank, dalpha: np.ndarray, dt_s: float, C_b_b0: np.ndarray,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        """Predict ``fine`` over the control step (Δα (3,) m/s in b0 axes, ``dt_s``, ending at body attitude
        C_b^{b0}) and fold each measurement whose aiding is there and whose kind is ``fresh`` (per kind of ``aids``:
        an epoch the filter has not had; the same two epochs interpolated again are not a new measurement)."""
        fine.predict(dalpha, dt_s, C_b_b0)
        if aid is not None and fresh.any():
            for kind, name, value in self.measurements(aid):
                if fresh[self._kind_index[kind]] and np.isfinite(value).all():
                    fine.update(name, value)

    def handover_solution(self, t_end: float, q_b_b0: np.ndarray, notice: tuple[str, str] | None
                          ) -> AttitudeSolution | None:
        """The coarse solution at the step's end to start the filter from, or None while its heading σ is above
        ``handover_limit_key``: a linear filter started several degrees off turns overconfident
        (seed 003 at 20 m/s: a 4°-σ window left 3-5° errors at σ 0.3°). ``notice`` (what comes before and after
        "heading σ … > …") tells the operator once why the coarse stage goes on; None: nothing to tell."""
        p = self.p
        solution = p.coarse.solution_at(t_end, q_b_b0)
        limit = functools.reduce(getattr, self.handover_limit_key.split("."), p.config)
        if solution.heading_sigma_deg <= limit:
            return solution
        if notice is not None:
            p.last_notice = p.last_notice or (f"{notice[0]}heading σ {solution.heading_sigma_deg:.2f}° > "
                                              f"{self.handover_limit_key} {limit:g}°{notice[1]}")
        return None

    def counters(self) -> dict[str, int]:
        """Each measurement's updates the filter accepted and its gate turned away (``<name>_accepted``,
        ``<name>_rejected``; none before the filter exists)."""
        fine = self.p.fine
        return {} if fine is None else {f"{name}_{what}": getattr(c, what) for name, c in fine.counters.items()
                                        for what in ("accepted", "rejected")}

    def record(self, t_epoch: float, t_sample: float, q_b_b0: np.ndarray,
               coarse: InertialCoarseAlignment) -> ResultRecord:
        """The coarse solution's record until the filter runs; then the filter's attitude with its σ (×
        :attr:`sigma_margin`), converged once σ is within the threshold and the data have confirmed the datasheet
        (:class:`~.datasheet_bank.MixtureSigma`)."""
        p = self.p
        threshold = p.config.alignment.converged_heading_sigma_deg
        if p.fine is None or not p.fine.active:
            return coarse_record(coarse.solution_at(t_sample, q_b_b0), t_epoch, threshold, p.fine is not None)
        C_b_b0 = dcm_from_quat(q_b_b0)
        sigma = p.fine.sigma_about(C_b_b0, t_sample - p.t_step)
        C_b_n = p.fine.attitude(C_b_b0, t_sample - p.t_step)
        m = self.sigma_margin
        heading_sigma_deg, level_sigma_deg = m * sigma.heading_deg, m * sigma.level_deg
        contradicted = p.fine.contradicted()
        if contradicted is not None:
            # the filter does not fit its data: its σ says nothing, and the operator is told why once
            heading_sigma_deg = level_sigma_deg = SIGMA_UNKNOWN_DEG
            name, seconds = contradicted
            p.last_notice = p.last_notice or (
                f"the Kalman stage has rejected every {name} update for {seconds:.1f} s: its model does not fit the "
                "data (an IMU worse than its datasheet, a wrong lever arm or latency); σ is unknown until it fits "
                "again: check [sensor] or the log's datasheet keys")
        if p.fine.believed:
            bias, noise = p.fine.hypotheses[p.fine.believed]
            p.last_notice = p.last_notice or (
                f"the {self.aids_text()} data fit an IMU {bias:g}× worse in bias and {noise:g}× in noise than its "
                "datasheet: the attitude and σ follow that; check [sensor] or the log's datasheet keys")
        solution = AttitudeSolution(t_sample, quat_from_dcm(C_b_n), heading_sigma_deg, level_sigma_deg,
                                    coarse.solver.rho, coarse.solver.trace_P, coarse.solver.n_obs)
        record = result_record(solution, t_epoch, "aligned" if heading_sigma_deg <= threshold else "fine", threshold)
        if record.converged and not sigma.confirmed:
            # σ is the datasheet's until the data have told it from a worse IMU that would change it (datasheet_bank)
            return replace(record, phase="fine", converged=False)
        return record
