"""Compass fine alignment with optional stored-data passes, driven one control step at a time.

Pure computation, no I/O. The caller (service/pipeline.py) feeds every control step from the
start of the data: :meth:`FineAlignment.feed` stores the first ``stored_data_s`` seconds and, once
the loops run, advances them. When the store fills while the loops run, the backward/forward
passes start on a clone (stored.py) and run ``pass_steps`` steps per control step (None: all at
once, as in offline replay); the clone then replaces the live state.
"""
from __future__ import annotations

import numpy as np

from .compass import CompassLoops, CompassState, GainSchedule
from .earth import Site
from .sensor_model import AttitudeSigma, SensorGrade
from .stored import RepeatedNavigation, StepBuffer


class FineAlignment:
    """Compass loops for one site and grade.

    Parameters
    ----------
    schedule : loop bandwidths against loop time.
    control_interval_s : nominal control step (s); sizes the store.
    stored_data_s : seconds of steps kept for the passes (0: no passes).
    stored_pairs : backward + forward pairs run over them.
    pass_steps : steps of pass work per live control step; None runs the passes at once.
    """

    def __init__(self, site: Site, grade: SensorGrade, schedule: GainSchedule, control_interval_s: float,
                 stored_data_s: float = 80.0, stored_pairs: int = 3, pass_steps: int | None = None) -> None:
        self.loops = CompassLoops(site, grade, schedule)
        self.pass_steps = pass_steps
        self.pairs = stored_pairs
        capacity = round(stored_data_s / control_interval_s) if stored_pairs > 0 else 0
        self.buffer = StepBuffer(capacity)
        self.state: CompassState | None = None
        self.passes: RepeatedNavigation | None = None
        self.passes_done = capacity == 0

    @property
    def active(self) -> bool:
        return self.state is not None

    def report_with(self, grade: SensorGrade) -> None:
        """The loops' covariance runs with ``grade`` (the noise the data show) once they start; after that it runs
        on with the grade it started with, so live passes sliced over many steps propagate it as offline passes
        run at once do. The biases σ adds to it (no part of the propagation) follow ``grade`` at any time."""
        self.loops.bias_grade = grade
        if not self.active:
            self.loops.grade = grade

    def start(self, C_b_n: np.ndarray, C_b_b0: np.ndarray, tilt_sigma_rad: float, heading_sigma_rad: float,
              t_loop_s: float = 0.0) -> None:
        """Hand-over: start the loops from attitude C_b^n (3, 3) with its 1-sigma noise errors,
        entering the gain schedule at ``t_loop_s``."""
        self.state = self.loops.start(C_b_n, C_b_b0, tilt_sigma_rad, heading_sigma_rad, t_loop_s)

    def feed(self, dalpha_b0: np.ndarray, dt_s: float) -> None:
        """One control step of data: Δα (3,) m/s in b0 axes over the last ``dt_s`` seconds."""
        if not self.buffer.full:
            self.buffer.append(dalpha_b0, dt_s)
            if self.buffer.full and self.state is None:
                self.passes_done = True   # the loops started too late to use the store
        if self.state is None:
            return
        self.loops.step(self.state, dalpha_b0, dt_s)
        if self.passes is None and not self.passes_done and self.buffer.full:
            self.passes = RepeatedNavigation(self.loops, self.state, self.buffer, self.pairs)
        elif self.passes is not None:
            self.passes.queue(dalpha_b0, dt_s)
        if self.passes is not None and self.passes.run(self.pass_steps):
            self.state = self.passes.state
            self.passes, self.passes_done = None, True

    def attitude(self, C_b_b0: np.ndarray, since_step_s: float) -> np.ndarray:
        """C_b^n (3, 3) of the body attitude C_{b}^{b0}, ``since_step_s`` after the last control step: the platform
        turned on at the rate the state commands."""
        return self.loops.attitude(self.state, C_b_b0, since_step_s)

    def record_angles(self, lat: float, elapsed_s: float, q_b_n0: np.ndarray, q_b_b0: np.ndarray,
                      coarse_sigma_deg: tuple[float, float], since_step_s: float) -> tuple[tuple, tuple]:
        """(the record's angles as ``_attitude.record_angles`` gives them, the loops' (heading, level) σ in degrees)
        of the output rule beside the coarse stage: :meth:`CompassLoops.record_angles`."""
        sigma = self.sigma
        fine_sigma_deg = (sigma.heading_deg, sigma.level_deg)
        return self.loops.record_angles(self.state, lat, elapsed_s, q_b_n0, q_b_b0, coarse_sigma_deg, fine_sigma_deg,
                                        since_step_s), fine_sigma_deg

    @property
    def sigma(self) -> AttitudeSigma:
        return self.loops.sigma(self.state)

    @property
    def schedule_complete(self) -> bool:
        """The gains have reached their final values and no passes are pending."""
        return self.passes_done and self.state.t_loop_s >= self.loops.schedule.final_time_s
