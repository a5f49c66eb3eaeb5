"""Which datasheet the data believe: the Kalman stage under the IMU's stated figures and under looser ones.

A filter whose datasheet understates its IMU is confidently wrong: the biases' prior holds their estimates near zero,
the process noise lets σ shrink faster than the error, and each update still looks plausible on its own (the aiding's
noise dominates the innovation's covariance). What tells is the record of innovations as a whole: a model that
predicted its data better has the larger likelihood. The bank runs one filter per hypothesis (:data:`HYPOTHESES`: the
datasheet, and its biases and noise densities some times worse) on the same steps and measurements, weighs them by
their likelihood (each as likely as the other before the data: the case to guard against is the datasheet that is
wrong), and reports

- the attitude of the datasheet's filter while its likelihood is the largest; once the data favour another, of the
  loosest hypothesis they have not ruled out (within e^-:data:`RULED_OUT_LOG` of the best likelihood): a datasheet
  proved wrong is no bound on how wrong it is (a MEMS gyro stated as tactical fits 10× for seconds before 100× wins);
- σ of the mixture about that attitude (each filter's own σ and its distance from the reported attitude, by weight),
  never below the reported filter's own: until the data have told the hypotheses apart, σ holds what a worse IMU
  would leave, and a datasheet filter that has wandered from the looser ones does not report itself converged.

On data that fit the datasheet the looser filters fall some nats behind within seconds (their wide priors and noise
predict the aiding less sharply) and their weight vanishes: the attitude and σ are the datasheet filter's. What a
datasheet cannot show in so few seconds, a tenfold one cannot either: σ waits for the data that tell them apart.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .conventions import DEG, quat_from_dcm, rotvec_from_quat
from .kalman import ErrorStateFilter, MeasurementCounters
from .sensor_model import AttitudeSigma, SensorGrade

HYPOTHESES = ((1.0, 1.0), (10.0, 10.0), (100.0, 10.0), (100.0, 100.0))
"""(the biases' scale, the noise densities' scale) against the datasheet, tightest first: the datasheet, a tenfold
understated one, a MEMS IMU stated as tactical (its biases a hundredfold, its noise some times), and a hundredfold."""
RULED_OUT_LOG = 10.0
"""A hypothesis whose likelihood is this much (natural log) below the best one's is ruled out (e^-10: 1 in 22 000)."""


def scaled_grade(grade: SensorGrade, scale: tuple[float, float]) -> SensorGrade:
    """``grade`` with its biases and noise densities ``scale`` times larger (the data's own base motion as it is)."""
    bias, noise = scale
    return SensorGrade(grade.gyro_bias_rad_s * bias, grade.gyro_arw_rad_rts * noise, grade.acc_bias_ms2 * bias,
                       grade.acc_vrw_ms_rts * noise, grade.base_motion_m_rts)


class DatasheetBank:
    """The filters of each hypothesis, all fed the same steps and measurements (the face of
    :class:`~.kalman.ErrorStateFilter` the modes use). ``make`` builds a filter of a grade."""

    def __init__(self, make: Callable[[SensorGrade], ErrorStateFilter], grade: SensorGrade,
                 hypotheses: Sequence[tuple[float, float]] = HYPOTHESES) -> None:
        self.hypotheses = tuple(hypotheses)
        self.members = [make(scaled_grade(grade, scale)) for scale in self.hypotheses]
        self.believed = 0
        """The hypothesis whose filter's attitude is reported (0: the datasheet)."""

    @property
    def filter(self) -> ErrorStateFilter:
        """The reported hypothesis's filter."""
        return self.members[self.believed]

    @property
    def active(self) -> bool:
        return self.members[0].active

    @property
    def measurements(self) -> dict:
        return self.members[0].measurements

    @property
    def counters(self) -> dict[str, MeasurementCounters]:
        """The datasheet filter's counts (a looser filter's would jump when it is reported)."""
        return self.members[0].counters

    def start(self, C_b_n: np.ndarray, C_b_b0: np.ndarray, V_n: np.ndarray, position: np.ndarray,
              tilt_sigma_rad: float, heading_sigma_rad: float, velocity_sigma_mps: float, **options) -> None:
        """Start every filter (:meth:`ErrorStateFilter.start`) from the same attitude and σ."""
        for member in self.members:
            member.start(C_b_n, C_b_b0, V_n, position, tilt_sigma_rad, heading_sigma_rad, velocity_sigma_mps,
                         **options)
        self.believed = 0

    def predict(self, dalpha_b0: np.ndarray, dt_s: float, C_b_b0: np.ndarray) -> None:
        for member in self.members:
            member.predict(dalpha_b0, dt_s, C_b_b0)

    def update(self, name: str, value: np.ndarray) -> bool:
        """Fold the measurement into every filter and weigh the hypotheses again; the datasheet filter's verdict."""
        accepted = [member.update(name, value) for member in self.members]
        likelihood = self._likelihoods()
        if int(np.argmax(likelihood)) == 0:
            self.believed = 0
        else:
            self.believed = int(np.flatnonzero(likelihood >= likelihood.max() - RULED_OUT_LOG)[-1])
        return accepted[0]

    def _likelihoods(self) -> np.ndarray:
        return np.array([member.log_likelihood for member in self.members])

    def weights(self) -> np.ndarray:
        """Each hypothesis's posterior probability (equal priors)."""
        likelihood = self._likelihoods()
        w = np.exp(likelihood - likelihood.max())
        return w / w.sum()

    def set_covariance(self, states: np.ndarray, block: np.ndarray) -> None:
        for member in self.members:
            member.set_covariance(states, block)

    def attitude(self, C_b_b0: np.ndarray, since_step_s: float = 0.0) -> np.ndarray:
        return self.filter.attitude(C_b_b0, since_step_s)

    def sigma_about(self, C_b_b0: np.ndarray, since_step_s: float = 0.0) -> AttitudeSigma:
        """1-sigma heading and level (deg) of the mixture about the reported attitude (of body attitude C_b^{b0},
        ``since_step_s`` after the last step), at least the reported filter's own."""
        reported = self.attitude(C_b_b0, since_step_s)
        heading_var = level_var = 0.0
        for w, member in zip(self.weights(), self.members, strict=True):
            # the member's attitude from the reported one, as a rotation in n (E, N, U) axes
            d = rotvec_from_quat(quat_from_dcm(member.attitude(C_b_b0, since_step_s) @ reported.T))
            own = member.sigma
            heading_var += w * ((own.heading_deg * DEG) ** 2 + d[2] ** 2)
            level_var += w * ((own.level_deg * DEG) ** 2 + max(d[0] ** 2, d[1] ** 2))
        own = self.filter.sigma
        return AttitudeSigma(max(float(np.sqrt(heading_var)) / DEG, own.heading_deg),
                             max(float(np.sqrt(level_var)) / DEG, own.level_deg))

    def contradicted(self) -> tuple[str, float] | None:
        return self.filter.contradicted()

    @property
    def x(self) -> np.ndarray:
        return self.filter.x

    @property
    def P(self) -> np.ndarray:
        return self.filter.P

    def extra_slice(self, name: str) -> slice:
        return self.filter.extra_slice(name)

    def extra(self, name: str) -> np.ndarray:
        """The reported filter's extra states of measurement ``name``."""
        return self.filter.extra(name)
