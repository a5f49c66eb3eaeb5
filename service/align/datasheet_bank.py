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
  would leave, and a datasheet filter that has wandered from the looser ones does not report itself converged;
- whether the datasheet is confirmed (:class:`MixtureSigma`): the datasheet's filter may call itself converged only
  once the hypotheses that would change its answer (a filter whose σ about the reported attitude is over
  :data:`WIDER` times the datasheet filter's) hold less than 1 − :data:`CONFIRMED` of the weight. In the first seconds
  every filter still holds the attitude it started from, and the weights of the looser ones, small but not yet
  negligible, leave the mixture's σ near the datasheet's: a MEMS IMU stated as tactical was converged 0.2-0.4° off
  under σ 0.06-0.08° (3-5σ) at 2-5 s after the hand-over, the tenfold hypothesis, its level σ five times the
  datasheet's, still at 2.5-5 % of the weight, before the data turned to the 100× one at 6 s. Hypotheses that
  give the same answer need not be told apart: on a GNSS flight a navigation IMU and one ten times worse agree.

On data that fit the datasheet the looser filters fall some nats behind within seconds (their wide priors and noise
predict the aiding less sharply) and their weight vanishes: the attitude and σ are the datasheet filter's. What a
datasheet cannot show in so few seconds, a tenfold one cannot either: σ waits for the data that tell them apart.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .conventions import DEG, quat_from_dcm, rotvec_from_quat
from .kalman import ErrorStateFilter, MeasurementCounters
from .sensor_model import SensorGrade

HYPOTHESES = ((1.0, 1.0), (10.0, 10.0), (100.0, 10.0), (100.0, 100.0))
"""(the biases' scale, the noise densities' scale) against the datasheet, tightest first: the datasheet, a tenfold
understated one, a MEMS IMU stated as tactical (its biases a hundredfold, its noise some times), and a hundredfold."""
RULED_OUT_LOG = 10.0
"""A hypothesis whose likelihood is this much (natural log) below the best one's is ruled out (e^-10: 1 in 22 000)."""
CONFIRMED = 0.99
"""The datasheet is confirmed once the hypotheses that would change its answer hold less than 1 − this of the weight."""
WIDER = 2.0
"""A hypothesis changes the answer if its filter's σ about the reported attitude (its own and its distance, heading or
level) is over this many times the datasheet filter's: it would at least double the σ claimed."""


@dataclass(frozen=True, slots=True)
class MixtureSigma:
    """1-sigma heading and level (deg) of the bank's mixture about the reported attitude, and whether the data have
    confirmed the datasheet (module docstring): only then may the datasheet's σ be called converged."""

    heading_deg: float
    level_deg: float
    confirmed: bool


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

    def sigma_about(self, C_b_b0: np.ndarray, since_step_s: float = 0.0) -> MixtureSigma:
        """1-sigma heading and level (deg) of the mixture about the reported attitude (of body attitude C_b^{b0},
        ``since_step_s`` after the last step), at least the reported filter's own; confirmed where a looser
        hypothesis is reported (its σ holds the datasheet's and its own) or the data have confirmed the datasheet."""
        reported = self.attitude(C_b_b0, since_step_s)
        weights = self.weights()
        about = np.empty((len(self.members), 2))   # each member's (heading, level) variance about the reported
        for k, member in enumerate(self.members):
            # the member's attitude from the reported one, as a rotation in n (E, N, U) axes
            d = rotvec_from_quat(quat_from_dcm(member.attitude(C_b_b0, since_step_s) @ reported.T))
            own = member.sigma
            about[k] = ((own.heading_deg * DEG) ** 2 + d[2] ** 2,
                        (own.level_deg * DEG) ** 2 + max(d[0] ** 2, d[1] ** 2))
        heading_var, level_var = weights @ about
        own = self.filter.sigma
        datasheet = self.members[0].sigma
        wider = (about > (WIDER * DEG * np.array([datasheet.heading_deg, datasheet.level_deg])) ** 2).any(axis=1)
        confirmed = self.believed != 0 or float(weights[1:][wider[1:]].sum()) < 1.0 - CONFIRMED
        return MixtureSigma(max(float(np.sqrt(heading_var)) / DEG, own.heading_deg),
                            max(float(np.sqrt(level_var)) / DEG, own.level_deg), confirmed)

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
