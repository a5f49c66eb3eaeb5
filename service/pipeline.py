"""The alignment pipeline: IMU samples in, result records at the output epochs out.

It owns the policy around the estimators: which solver, when to emit (epochs on the IMU
samples at whole multiples of the output period), the phase and the ``converged`` flag
(``heading_sigma_deg`` at or below the configured threshold). The estimators stay pure.
"""
from __future__ import annotations

import numpy as np

from ..protocol.results import ResultRecord
from .align.coarse import AttitudeSolution, InertialCoarseAlignment
from .align.conventions import DEG, dcm_from_quat, euler_from_dcm
from .align.earth import Site
from .align.observations import FixedSiteSource
from .align.sensor_model import SensorGrade
from .align.solvers import RecursiveK
from .config import Config, ConfigError


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
                        converged=solution.heading_sigma_deg <= threshold_deg, rho=float(solution.rho),
                        trace_P=float(solution.trace_P), n_obs=solution.n_obs)


class AlignmentPipeline:
    """Coarse alignment of a base fixed in position, emitting records at the output epochs.

    Parameters
    ----------
    config : validated configuration.
    site : position of the IMU.
    rate_hz : nominal IMU sample rate.
    datasheet : the log's datasheet keys, if any (override ``config.sensor``).
    """

    def __init__(self, config: Config, site: Site, rate_hz: float, datasheet: dict[str, float] | None = None) -> None:
        a = config.alignment
        self.config = config
        self.sample_period_s = 1.0 / rate_hz
        if a.obs_interval_s < self.sample_period_s:
            raise ConfigError(f"alignment.obs_interval_s: {a.obs_interval_s} s is shorter than the IMU sample "
                              f"period {self.sample_period_s:g} s ({rate_hz:g} Hz)")
        self.period_s = config.output.period_s
        self.coarse = InertialCoarseAlignment(
            FixedSiteSource(site), grade_from(config, datasheet), RecursiveK(a.solver, a.request_rho),
            self.sample_period_s, a.obs_interval_s, a.disturbance_velocity_mps)
        self._epoch_count: int | None = None

    def _epoch_counts(self, t: np.ndarray) -> np.ndarray:
        # the sample within half a period of k·P carries epoch k
        return np.floor((t + 0.5 * self.sample_period_s) / self.period_s).astype(np.int64)

    def process(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> list[ResultRecord]:
        """Feed N samples (t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s); return the records due in them."""
        if len(t) == 0:
            return []
        counts = self._epoch_counts(np.asarray(t, dtype=float))
        if self._epoch_count is None:
            self._epoch_count = int(self._epoch_counts(np.asarray([t[0] - self.sample_period_s]))[0])
        records = []
        start = 0
        for end in np.flatnonzero(np.diff(counts, prepend=self._epoch_count) > 0):
            self.coarse.update_block(t[start:end + 1], dtheta[start:end + 1], dv[start:end + 1])
            start = end + 1
            t_epoch = round(float(counts[end]) * self.period_s, 9)
            records.append(result_record(self.coarse.solution, t_epoch, "coarse",
                                         self.config.alignment.converged_heading_sigma_deg))
        self.coarse.update_block(t[start:], dtheta[start:], dv[start:])
        self._epoch_count = int(counts[-1])
        return records
