"""In motion with an odometer or DVL (seed 003): body velocity V^b (3 aiding values per sample, m/s).

Observation source: body velocity at each observation over a bounded stored window, the multistage re-runs every
``aiding.odo.relevel_interval_s``. Fine stage: the error-state Kalman filter with body-velocity measurements (scale
factor and lever arm as states if their priors are set), from the end of the window once its heading σ is within
``fine.kalman.handover_heading_sigma_deg``. No translation check: this base is meant to move.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..align.coarse import InertialCoarseAlignment
from ..align.conventions import DEG, dcm_from_quat
from ..align.datasheet_bank import DatasheetBank
from ..align.kalman import BodyVelocity
from ..align.solvers import make_solver
from ..align.velocity_aided import MultistageCoarseAlignment, VelocityAidedSource
from .kalman import KalmanMode

if TYPE_CHECKING:
    from ..config import AidingConfig

HANDOVER_VELOCITY_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n from one odometer reading: its σ is this many times the reading's."""


def odometer_measurement(ad: AidingConfig) -> BodyVelocity:
    """The Kalman stage's body-velocity measurement (its scale factor and lever arm as states if their priors are
    set)."""
    return BodyVelocity(ad.odo.vel_std_mps, np.array(ad.odo.lever_m), ad.odo.scale_sigma, ad.odo.lever_sigma_m)


class Odometer(KalmanMode):
    aids = (("odo", 3),)
    coarse_kind = "odo"

    def make_coarse(self) -> InertialCoarseAlignment:
        p = self.p
        a, ad = p.config.alignment, p.config.aiding
        priors = {"acc_bias_sigma_ms2": p.grade.acc_bias_ms2, "odo_scale_sigma": ad.odo.scale_sigma,
                  "odo_lever_m": np.array(ad.odo.lever_m), "odo_lever_sigma_m": ad.odo.lever_sigma_m}
        source = VelocityAidedSource(p.site, ad.odo.window_s, a.obs_interval_s, ad.odo.levels, ad.odo.solver, priors)
        self._next_relevel_s = ad.odo.relevel_interval_s
        self._window_solved = False
        return MultistageCoarseAlignment(source, p.grade, make_solver(ad.odo.solver, a.request_rho),
                                         p.sample_period_s, a.obs_interval_s, a.disturbance_velocity_mps)

    def make_fine(self) -> DatasheetBank | None:
        return self.filter_bank(lambda: [odometer_measurement(self.p.config.aiding)])

    def measurements(self, aid: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        return [("odo", "odo", aid)]

    def step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray, dt_s: float,
             aid: np.ndarray | None, fresh: np.ndarray) -> None:
        p = self.p
        C_b_b0 = dcm_from_quat(q_b_b0)
        if self.kalman_step(dalpha, dt_s, C_b_b0, aid, fresh):
            return
        aided = aid is not None and bool(np.isfinite(aid).all())
        source: VelocityAidedSource = p.coarse.source
        if aided and source.C_b0_n0 is not None:
            source.advance(elapsed_s, C_b_b0, aid)   # C_n^{n0} with transport rate between re-runs, and after
        # the levels run one per control step (a re-run of the full window costs tens of ms at once)
        due = elapsed_s + 1e-9 >= self._next_relevel_s or source.window_full(elapsed_s)
        if not source.relevelling and not self._window_solved and due and p.coarse.start_relevel(elapsed_s):
            self._next_relevel_s = elapsed_s + p.config.aiding.odo.relevel_interval_s
        if source.relevelling and source.step_relevel(1):
            self._window_solved = source.relevel_window_full
        if p.fine is not None and self._window_solved and aided:
            # the window is all there is: above the limit the coarse stage stays
            solution = self.handover_solution(t_end, q_b_b0, (f"the {p.config.aiding.odo.window_s:g}-s window gives ",
                                                              ": no fine stage; lengthen aiding.odo.window_s"))
            if solution is None:
                return
            C_b_n = dcm_from_quat(solution.q_b_n)
            result = source.result
            odometer = p.fine.measurements["odo"]
            known = {"odo_scale": odometer.scale, "odo_lever": odometer.lever}
            extra = [(result.nuisance[k], result.nuisance_sigma[k]) for k in ("odo_scale", "odo_lever")
                     if known[k] and k in result.nuisance]
            p.fine.start(C_b_n, C_b_b0, C_b_n @ aid, source.position, solution.level_sigma_deg * DEG,
                         solution.heading_sigma_deg * DEG, HANDOVER_VELOCITY_SIGMA_FACTOR * odometer.std_mps,
                         extra={"odo": tuple(np.concatenate(pair) for pair in zip(*extra, strict=True))} if extra
                         else None)

    def counters(self) -> dict[str, int]:
        """The filter's counts, and the multistage pairs left out as outliers."""
        result = self.p.coarse.source.result
        return {**super().counters(), "odo_outlier_pairs": 0 if result is None else int((~result.kept).sum())}


MODE = Odometer
"""The mode this module declares (:data:`~service.modes.MODES`)."""
