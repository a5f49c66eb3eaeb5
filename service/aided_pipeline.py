"""The velocity-aided alignment pipeline (odometer / DVL, seed 003): the same pipeline, other parts.

It is :class:`AlignmentPipeline` with three parts swapped: the observation source (body velocity
at each observation, a bounded stored window, multistage re-runs every ``relevel_interval_s``),
the fine stage (the error-state Kalman filter with body-velocity measurements, from the end of the
window), and no translation check (this base is meant to move). Blocks, records, phases and the
bit-identity of stream and replay are the base class's.
"""
from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .align.coarse import InertialCoarseAlignment
from .align.conventions import DEG, dcm_from_quat
from .align.earth import Site
from .align.kalman import BodyVelocity, ErrorStateFilter
from .align.solvers import make_solver
from .align.velocity_aided import MultistageCoarseAlignment, VelocityAidedSource
from .config import Config, ConfigError
from .gnss_pipeline import GnssAidedPipeline
from .kalman_stage import KalmanStagePipeline
from .pipeline import AlignmentPipeline
from .transfer_pipeline import TransferPipeline

HANDOVER_VELOCITY_SIGMA_FACTOR = 3.0
"""The Kalman stage starts with V^n from one odometer reading: its σ is this many times the reading's."""


class VelocityAidedPipeline(KalmanStagePipeline):
    """Alignment of a moving base with body velocity V^b (3 aiding values per sample, m/s)."""

    aid_width = 3
    aid_kind = "odo"
    checks_translation = False

    def _make_coarse(self) -> InertialCoarseAlignment:
        a, ad = self.config.alignment, self.config.aiding
        priors = {"acc_bias_sigma_ms2": self.grade.acc_bias_ms2, "odo_scale_sigma": ad.odo_scale_sigma,
                  "odo_lever_m": np.array(ad.odo_lever_m), "odo_lever_sigma_m": ad.odo_lever_sigma_m}
        source = VelocityAidedSource(self.site, ad.window_s, a.obs_interval_s, ad.levels, ad.solver, priors)
        self._next_relevel_s = ad.relevel_interval_s
        self._window_solved = False
        return MultistageCoarseAlignment(source, self.grade, make_solver(ad.solver, a.request_rho),
                                         self.sample_period_s, a.obs_interval_s, a.disturbance_velocity_mps)

    def _make_fine(self) -> ErrorStateFilter | None:
        if not self.config.fine.enabled:
            return None
        ad = self.config.aiding
        odometer = BodyVelocity(ad.odo_std_mps, np.array(ad.odo_lever_m), ad.odo_scale_sigma, ad.odo_lever_sigma_m)
        return ErrorStateFilter(self.grade, [odometer], ad.gate_chi2)

    def _measurements(self, aid: np.ndarray) -> list[tuple[str, np.ndarray]]:
        return [("odo", aid)]

    def _stage_step(self, t_end: float, elapsed_s: float, q_b_b0: np.ndarray, dalpha: np.ndarray,
                    dt_s: float, aid: np.ndarray | None, fresh: bool) -> None:
        C_b_b0 = dcm_from_quat(q_b_b0)
        if self._kalman_step(dalpha, dt_s, C_b_b0, aid, fresh):
            return
        aided = aid is not None and bool(np.isfinite(aid).all())
        source: VelocityAidedSource = self.coarse.source
        if aided and source.C_b0_n0 is not None:
            source.advance(elapsed_s, C_b_b0, aid)   # C_n^{n0} with transport rate between re-runs, and after
        # the levels run one per control step (a re-run of the full window costs tens of ms at once)
        due = elapsed_s + 1e-9 >= self._next_relevel_s or source.window_full(elapsed_s)
        if not source.relevelling and not self._window_solved and due and self.coarse.start_relevel(elapsed_s):
            self._next_relevel_s = elapsed_s + self.config.aiding.relevel_interval_s
        if source.relevelling and source.step_relevel(1):
            self._window_solved = source.relevel_window_full
        if self.fine is not None and self._window_solved and aided:
            # the window is all there is: above the limit the coarse stage stays
            solution = self._handover_solution(t_end, q_b_b0, (f"the {self.config.aiding.window_s:g}-s window gives ",
                                                               ": no fine stage; lengthen aiding.window_s"))
            if solution is None:
                return
            C_b_n = dcm_from_quat(solution.q_b_n)
            result = source.result
            odometer = self.fine.measurements["odo"]
            known = {"odo_scale": odometer.scale, "odo_lever": odometer.lever}
            extra = [(result.nuisance[k], result.nuisance_sigma[k]) for k in ("odo_scale", "odo_lever")
                     if known[k] and k in result.nuisance]
            self.fine.start(C_b_n, C_b_b0, C_b_n @ aid, source.position, solution.level_sigma_deg * DEG,
                            solution.heading_sigma_deg * DEG, HANDOVER_VELOCITY_SIGMA_FACTOR * odometer.std_mps,
                            extra={"odo": tuple(np.concatenate(p) for p in zip(*extra, strict=True))} if extra
                            else None)

    def aiding_counters(self) -> dict[str, int]:
        """What the estimators made of the aiding: observations awaiting or without it, multistage pairs left out as
        outliers, and the Kalman stage's accepted and gated-out odometer readings."""
        result = self.coarse.source.result
        return {**super().aiding_counters(), "odo_outlier_pairs": 0 if result is None else int((~result.kept).sum())}


AIDED_MODES = {frozenset(): AlignmentPipeline, frozenset({"odo"}): VelocityAidedPipeline,
               frozenset({"gnss"}): GnssAidedPipeline, frozenset({"master"}): TransferPipeline}
"""Which pipeline the aids given select (``replay --aid``, the daemon's ``aid/<kind>`` inputs)."""


def build_pipeline(config: Config, site: Site, rate_hz: float, datasheet: dict[str, float] | None = None,
                   aids: Iterable[str] = (), live: bool = False) -> AlignmentPipeline:
    """The pipeline of the mode the aiding kinds ``aids`` select. What an aiding log states of its sensor (noise,
    lever arm) belongs in ``config.aiding`` (the replay puts it there)."""
    kinds = frozenset(aids)
    if kinds not in AIDED_MODES:
        known = ", ".join(sorted("+".join(sorted(k)) or "(none)" for k in AIDED_MODES))
        raise ConfigError(f"aids {', '.join(sorted(kinds))}: no aided mode for this combination yet (known: {known})")
    return AIDED_MODES[kinds](config, site, rate_hz, datasheet, live)
