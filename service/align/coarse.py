"""Streaming inertial-frame coarse alignment (seed 000; docs/algorithms/coarse.md).

Per sample: integrate C_{b(t)}^{b0} and α(t) (strapdown.py); every ``obs_interval_s`` take a
vector pair from the observation source and fold it into the recursive K-matrix solver
(solvers.py). The current attitude follows from the chain rule
``C_b^n(t) = C_{n0}^{n(t)} · C_b^n(0) · C_{b(t)}^{b0}``. Memory is O(1) whatever the run length.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from ._attitude import chained_quaternion
from .conventions import DEG, dcm_from_quat
from .observations import ObservationSource
from .sensor_model import SIGMA_UNKNOWN_DEG, SensorGrade, inertial_alignment_sigma
from .solvers import CentredWahba, RecursiveK, WhitenedWahba
from .strapdown import InertialIntegrator
from .swing_bias import SwingBias
from .turning_bias import TurningBiasTerm

_NONE_OBSERVED = np.empty(0), np.empty((0, 3))
_NOTHING_TO_FOLD = np.empty((0, 4, 4)), np.empty(0)
for _array in (*_NONE_OBSERVED, *_NOTHING_TO_FOLD):
    _array.flags.writeable = False


def stepped_up(values: np.ndarray, before: float) -> np.ndarray:
    """Where each of ``values`` (N,) exceeds the one before it (the first: ``before``): ``np.diff(values,
    prepend=before) > 0`` without diff's cost on the live path's few samples (the same for integers and for floats,
    NaN included: never)."""
    up = np.empty(len(values), dtype=bool)
    if len(values):
        up[0] = values[0] > before
        np.greater(values[1:], values[:-1], out=up[1:])
    return up


def _shallow_copy(obj: object) -> object:
    """``copy.copy`` of one of the stage's parts: its own ``__copy__`` if it has one, else a new object with a copy
    of its attributes (what copy.copy does for them, without its generic protocol: the live path takes a scratch
    per record)."""
    if hasattr(type(obj), "__copy__"):
        return copy.copy(obj)
    clone = object.__new__(type(obj))
    clone.__dict__.update(obj.__dict__)
    return clone


@dataclass(frozen=True, slots=True)
class AttitudeSolution:
    """The attitude estimate at one instant.

    t : time of the sample (s, input time base). q_b_n : [w, x, y, z] of C_b^n(t).
    heading_sigma_deg, level_sigma_deg : 1-sigma of the actual error, bias limit included.
    rho, trace_P : the solver's last gain and covariance trace; n_obs : observations used.
    """

    t: float
    q_b_n: np.ndarray
    heading_sigma_deg: float
    level_sigma_deg: float
    rho: float
    trace_P: float
    n_obs: int


class InertialCoarseAlignment:
    """Recursive OPREQ (or REQUEST / q-method) alignment in the inertial frame.

    Parameters
    ----------
    source : observation source (``FixedSiteSource(site)`` for a non-translating base).
    grade : datasheet sensor figures; set μ(t) and the reported σ.
    solver : the K-matrix estimator.
    sample_period_s : nominal IMU sample period (s); the start t0 is one period before the first
        sample's time stamp, since a sample's time marks the end of its interval.
    obs_interval_s : time between observations fed to the solver (s).
    disturbance_velocity_mps : bounded velocity-like disturbance of α in OPREQ's noise model (m/s).
    swing_bias : estimate the accelerometer bias seen through a swinging body and take its term out of α
        before the solver (a fixed site only: :mod:`.swing_bias`); None leaves α as integrated.
    turning_bias : add to σ what the accelerometer bias seen through a turning body does to the fit (a fixed site
        only: :mod:`.turning_bias`); None: σ is the time model's alone.
    """

    def __init__(self, source: ObservationSource, grade: SensorGrade, solver: RecursiveK | CentredWahba,
                 sample_period_s: float, obs_interval_s: float = 0.1, disturbance_velocity_mps: float = 1e-3,
                 swing_bias: SwingBias | None = None, turning_bias: TurningBiasTerm | None = None) -> None:
        if obs_interval_s < sample_period_s:
            raise ValueError("obs_interval_s must be at least one sample period")
        self.source = source
        self.grade = grade
        self.sigma_grade = grade   # the grade of the reported σ: the datasheet's, or the noise the data show
        self.solver = solver
        self.sample_period_s = sample_period_s
        self.obs_interval_s = obs_interval_s
        self.disturbance_velocity_mps = disturbance_velocity_mps
        self.swing_bias = swing_bias
        self.turning_bias = turning_bias
        self.integrator = InertialIntegrator()
        self._lat = source.site.lat
        self._gravity = source.site.gravity
        self.t0: float | None = None
        self.t: float | None = None
        self._obs_count = 0
        self.observations_awaiting_aid = 0   # due before the aid's first usable value: a wait, not a fault
        self.unaided_observations = 0        # due without aid after it had started: a dropout
        self.aid_started = False
        self._aid_epoch = -1.0   # the aiding epoch of the last observation
        self.observed = _NONE_OBSERVED
        """The last :meth:`observe`'s observations: elapsed time (M,) s and α (M, 3) m/s as the solver takes it (b0
        axes, the swing-bias term removed): what the fixed-base residual's noise is measured on."""

    def update(self, dtheta: np.ndarray, dv: np.ndarray, t: float) -> None:
        """One IMU sample: Δθ (3,) rad, Δv (3,) m/s in body axes, ending at time t (s)."""
        self.update_block(np.asarray([t], dtype=float), np.reshape(dtheta, (1, 3)), np.reshape(dv, (1, 3)))

    def update_block(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray) -> None:
        """N ≥ 1 consecutive samples: times t (N,) s, Δθ (N, 3) rad, Δv (N, 3) m/s."""
        elapsed, q_b_b0, alpha = self.integrate(t, dtheta, dv)
        due, dK, trace_R = self.observe(elapsed, q_b_b0, alpha)
        if len(due):
            self.solver.fold(dK, trace_R)

    def integrate(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray,
                  block_samples: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Strapdown integration of N samples (see :meth:`InertialIntegrator.integrate`).

        Returns the time since the start (N,) s, C_{b}^{b0} (N, 4) and α (N, 3) m/s at the samples.
        """
        t = np.asarray(t, dtype=float)
        if self.t0 is None:
            self.t0 = float(t[0]) - self.sample_period_s
        q_b_b0, alpha = self.integrator.integrate(dtheta, dv, block_samples)
        self.t = float(t[-1])
        return t - self.t0, q_b_b0, alpha

    def observe(self, elapsed_s: np.ndarray, q_b_b0: np.ndarray, alpha: np.ndarray, aid: np.ndarray | None = None,
                aid_epoch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The observations due among integrated samples: (sample indices, δK, tr R) for the solver's fold.

        ``aid`` (N, k): aiding values at the samples (NaN where none), for an aided source; an
        observation due at a sample without them is skipped and counted: as awaiting the aid before its
        first usable value (a receiver before its first fix), as unaided after it. ``aid_epoch`` (N,): the number
        of the newest aiding epoch at or before each sample; an observation due before a newer epoch
        than the last observation's is skipped (not counted): an aid slower than the observations
        gives one observation per epoch, not several interpolated from the same two. With none due the prepared
        arrays are empty placeholders that no fold is given.
        """
        # observation k is due at k·interval; a sample within half a period of it takes it
        counts = np.floor((elapsed_s + 0.5 * self.sample_period_s) / self.obs_interval_s).astype(np.int64)
        due = np.flatnonzero(stepped_up(counts, self._obs_count))
        self._obs_count = int(counts[-1])
        if aid is not None:
            usable = np.isfinite(aid[due]).all(axis=1)
            waiting = 0   # observations before the first usable one, while the aid has not started
            if not self.aid_started:
                self.aid_started = bool(usable.any())
                waiting = int(np.argmax(usable)) if self.aid_started else len(due)
            self.observations_awaiting_aid += waiting
            self.unaided_observations += int(len(due) - waiting - usable.sum())
            due = due[usable]
            if aid_epoch is not None:
                epoch = aid_epoch[due]
                due = due[stepped_up(epoch, self._aid_epoch)]
                self._aid_epoch = max(self._aid_epoch, float(epoch[-1])) if len(epoch) else self._aid_epoch
        if len(due) == 0:   # most calls of the live path: numpy's per-call cost on empty arrays is skipped
            self.observed = _NONE_OBSERVED
            return due, *_NOTHING_TO_FOLD
        alpha_due = alpha[due]
        if self.swing_bias is not None:
            alpha_due = self.swing_bias.correct(elapsed_s[due], alpha_due, q_b_b0[due])
        if self.turning_bias is not None:
            self.turning_bias.observe(elapsed_s[due], q_b_b0[due])
        self.observed = elapsed_s[due], alpha_due
        b, r = self.source.vectors(elapsed_s[due], alpha_due, q_b_b0[due], None if aid is None else aid[due])
        return (due, *self.prepare_pairs(elapsed_s[due], b, r))

    def prepare_pairs(self, elapsed_s: np.ndarray, b: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The solver's prepared pairs taken at ``elapsed_s``, with OPREQ's noise model μ of the unit vectors."""
        mu = self.grade.observation_variance(elapsed_s, self._gravity, self.disturbance_velocity_mps)
        if isinstance(self.solver, WhitenedWahba):   # it whitens the increments between the epochs itself
            return self.solver.prepare(b, r, mu, elapsed_s)
        return self.solver.prepare(b, r, mu)

    def report_with(self, grade: SensorGrade) -> None:
        """σ is reported with ``grade`` from now on (the noise the data show); the estimate keeps the datasheet's
        weights."""
        self.sigma_grade = grade

    def carry_aid_start(self, previous: InertialCoarseAlignment) -> None:
        """An aid that had begun for ``previous`` (the stage this one replaces) has begun here too."""
        self.aid_started = self.aid_started or previous.aid_started

    follows_aid = False
    """Whether :meth:`observe` changes the stage between its observations (an aided source that follows its aid at
    every sample): then no record ahead of the integrated samples can do without a scratch copy (:meth:`scratch`)."""

    def unchanged_until(self, t: float) -> bool:
        """Whether observing the samples after the integrated ones up to time ``t`` (s, input time base) would leave
        the stage as it is: none due by then (the count of :meth:`observe`, the same arithmetic) and no aid followed
        between observations. A record at such a sample takes this stage with the integrator run ahead."""
        if self.t0 is None or self.follows_aid:
            return False
        return math.floor((t - self.t0 + 0.5 * self.sample_period_s) / self.obs_interval_s) <= self._obs_count

    def scratch(self) -> InertialCoarseAlignment:
        """A copy to run ahead on and throw away: the state the updates replace is copied, nothing else.

        ``integrate``, ``observe`` and the solver's ``fold`` assign new arrays rather than write into
        the old ones, so shallow copies of the object, its integrator and its solver are independent.
        """
        clone = _shallow_copy(self)
        clone.integrator = _shallow_copy(self.integrator)
        clone.source = _shallow_copy(self.source)   # an aided source's store: the clone writes only past its end
        clone.solver = _shallow_copy(self.solver)
        clone.swing_bias = None if self.swing_bias is None else _shallow_copy(self.swing_bias)
        clone.turning_bias = None if self.turning_bias is None else _shallow_copy(self.turning_bias)
        return clone

    @property
    def q_b_n0(self) -> np.ndarray:
        """Estimate of the constant C_b^n(0) as [w, x, y, z]."""
        return self.solver.quaternion()

    def sigma(self, elapsed_s: float) -> tuple[float, float]:
        """Reported 1-sigma (heading, level) in degrees after ``elapsed_s`` of alignment: the time model's
        (:meth:`model_sigma`) with what the accelerometer bias seen through the body's turns adds."""
        heading_deg, level_deg = self.model_sigma(elapsed_s)
        if self.turning_bias is None or heading_deg >= SIGMA_UNKNOWN_DEG:
            return heading_deg, level_deg
        heading2, level2 = self.turning_bias.variances(elapsed_s, dcm_from_quat(self.q_b_n0),
                                                       self.sigma_grade.acc_bias_ms2)
        return (min(math.hypot(heading_deg, math.sqrt(heading2) / DEG), SIGMA_UNKNOWN_DEG),
                min(math.hypot(level_deg, math.sqrt(level2) / DEG), SIGMA_UNKNOWN_DEG))

    def model_sigma(self, elapsed_s: float) -> tuple[float, float]:
        """1-sigma (heading, level) in degrees of the time model alone (the grade σ is reported with, over the time
        since the start): the noise part the hand-over to the compass loops is judged on."""
        if self.solver.n_obs == 0:
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        sigma = inertial_alignment_sigma(self.sigma_grade, self._lat, self._gravity, elapsed_s)
        return sigma.heading_deg, sigma.level_deg

    def solution_at(self, t: float, q_b_b0: np.ndarray) -> AttitudeSolution:
        """The attitude C_b^n at sample time t whose body attitude is C_{b}^{b0} = ``q_b_b0``."""
        elapsed = 0.0 if self.t0 is None else t - self.t0
        q_b_n = chained_quaternion(self.source.C_n_n0(elapsed), np.ascontiguousarray(self.q_b_n0),
                                   np.ascontiguousarray(q_b_b0))
        heading_sigma, level_sigma = self.sigma(elapsed)
        return AttitudeSolution(t=t, q_b_n=q_b_n, heading_sigma_deg=heading_sigma,
                                level_sigma_deg=level_sigma, rho=self.solver.rho, trace_P=self.solver.trace_P,
                                n_obs=self.solver.n_obs)

    @property
    def solution(self) -> AttitudeSolution:
        """The current attitude C_b^n(t) with its uncertainty (after ``update``/``update_block``)."""
        return self.solution_at(self.t if self.t is not None else 0.0, self.integrator.q_b_b0)
