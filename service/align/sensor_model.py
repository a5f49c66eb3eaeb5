"""Sensor grade, the observation-noise model of OPREQ, and the accuracy limits (docs/algorithms/coarse.md).

A :class:`SensorGrade` holds datasheet 1-sigma figures in SI units. From it follow
- μ(t), the per-axis variance of the normalised observation b = α/|α| (OPREQ's noise model);
- the physical limit of the misalignment set by the actual biases (what no method removes);
- 1-sigma attitude uncertainties after an alignment time T, bias part plus noise part.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ._kernels import coarse_variances, coarse_variances_one
from .conventions import DEG, DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from .earth import OMEGA_IE

ESTIMATOR_EFFICIENCY = 2.0
"""Variance of the recursive OPREQ heading over the least-squares floor, measured by Monte Carlo
(``sinsalign eval``: seed-000 swing and turntable scenarios, ≈1.4² at 100-300 s)."""
SMALLEST_FIGURE = 1e-12
"""Floor of every datasheet figure in SI units (the simulator's ideal sensor states the same)."""
SIGMA_UNKNOWN_DEG = float(360.0 / np.sqrt(12.0))
"""1-sigma of an angle that is uniformly unknown over a full turn (103.9°): the cap of every σ."""


@dataclass(frozen=True, slots=True)
class SensorGrade:
    """Datasheet 1-sigma figures, the same on every axis, in SI units.

    gyro_bias_rad_s : in-run constant gyro bias (rad/s).
    gyro_arw_rad_rts : angle random walk (rad/√s).
    acc_bias_ms2 : accelerometer bias (m/s²).
    acc_vrw_ms_rts : velocity random walk (m/s/√s).
    base_motion_m_rts : a bounded disturbance of α (base motion, quantisation) as the data show it, seen as white
        noise of this density per axis (m/√s: √(variance × correlation time); service/align/noise_check.py). No
        datasheet states it.
    """

    gyro_bias_rad_s: float
    gyro_arw_rad_rts: float
    acc_bias_ms2: float
    acc_vrw_ms_rts: float
    base_motion_m_rts: float = 0.0

    @classmethod
    def from_datasheet(cls, gyro_bias_deg_h: float, gyro_arw_deg_rth: float, acc_bias_ug: float,
                       acc_vrw_ug_rthz: float) -> SensorGrade:
        """From the units of the IMU log's comment keys: °/h, °/√h, µg, µg/√Hz. A figure of 0 (a log may state an
        ideal sensor) is taken as :data:`SMALLEST_FIGURE`: the estimators divide by these."""
        figures = (gyro_bias_deg_h * DH_TO_RS, gyro_arw_deg_rth * DRH_TO_RRS, acc_bias_ug * UG_TO_MS2,
                   acc_vrw_ug_rthz * UG_TO_MS2)
        return cls(*(max(f, SMALLEST_FIGURE) for f in figures))

    def datasheet(self) -> dict[str, float]:
        """The figures in the IMU log's comment-key units (°/h, °/√h, µg, µg/√Hz)."""
        return {"gyro_bias_deg_h": self.gyro_bias_rad_s / DH_TO_RS,
                "gyro_arw_deg_rth": self.gyro_arw_rad_rts / DRH_TO_RRS,
                "acc_bias_ug": self.acc_bias_ms2 / UG_TO_MS2,
                "acc_vrw_ug_rthz": self.acc_vrw_ms_rts / UG_TO_MS2}

    def observation_variance(self, elapsed_s: np.ndarray, gravity: float,
                             disturbance_velocity_mps: float = 1e-3) -> np.ndarray:
        """μ(t) (rad², per axis) of b = α/|α| after ``elapsed_s`` of integration.

        Only errors that differ randomly between observations count. The biases are left out:
        a constant accelerometer bias tilts every α alike (the solver absorbs it as the level
        limit) and a gyro bias drifts C_b^{b0} the same way in every run (it makes the heading
        limit); counted as noise they flatten μ so that the first, least informative vectors
        weigh as much as the last, which slows settling and biases the heading. What remains:
        velocity random walk averaging down as VRW²/(g² t); a bounded velocity-like disturbance
        v_d (base motion, bias seen through the swinging body) shrinking as (v_d / g t)². The
        gyro angle random walk is left out as well: its tilt is the same growing error in every
        later α, and as independent noise (N² t / 3) it would discount the late vectors that
        carry the heading (measured: turntable scenario, seed-to-seed heading STD 0.128° with it,
        0.114° without).
        """
        t = np.maximum(np.asarray(elapsed_s, dtype=float), 1e-9)
        return self.acc_vrw_ms_rts**2 / (gravity**2 * t) + (disturbance_velocity_mps / (gravity * t)) ** 2


def physical_limit(acc_bias_n: np.ndarray, gyro_bias_n: np.ndarray, lat: float, gravity: float) -> np.ndarray:
    """Misalignment φ = (φ_E, φ_N, φ_U) in rad left by n-frame biases (docs/algorithms/coarse.md, "Accuracy limits").

    φ_E = -∇_N/g, φ_N = ∇_E/g, φ_U = ∇_E tan L / g - ε_E / (Ω cos L).
    ``acc_bias_n`` (m/s²) and ``gyro_bias_n`` (rad/s) are (..., 3) ENU vectors.
    """
    acc = np.asarray(acc_bias_n, dtype=float)
    gyro = np.asarray(gyro_bias_n, dtype=float)
    return np.stack((-acc[..., 1] / gravity, acc[..., 0] / gravity,
                     acc[..., 0] * np.tan(lat) / gravity - gyro[..., 0] / (OMEGA_IE * np.cos(lat))), axis=-1)


@dataclass(frozen=True, slots=True)
class AttitudeSigma:
    """1-sigma attitude uncertainty in degrees: heading and each horizontal tilt."""

    heading_deg: float
    level_deg: float


def bias_limit_rad(grade: SensorGrade, lat: float, gravity: float) -> tuple[float, float]:
    """1-sigma (heading, level) misalignment in rad that the datasheet biases leave (the bias limit)."""
    return _sigma_terms(grade, lat, gravity).bias_rad


@dataclass(frozen=True, slots=True)
class _SigmaTerms:
    """What σ(T) takes of a grade and site, computed once: the bias limit (rad) and the model's terms as the compiled
    σ model takes them (``_policy.pxi`` ``_coarse_variances``): in heading the accelerometer's white noise over T³
    (rad² s³), the gyro's angle random walk over T (rad² s) and a bounded disturbance of α over T⁵ (rad² s⁵), the bias
    limit², the gyro bias (rad/s); in level the bias limit², the accelerometer's noise over T, the walk times T and
    the disturbance over T³."""

    bias_rad: tuple[float, float]
    kernel: np.ndarray

    @property
    def acc_heading(self) -> float:
        return float(self.kernel[0])

    @property
    def gyro_heading(self) -> float:
        return float(self.kernel[1])


def _sigma_terms(grade: SensorGrade, lat: float, gravity: float) -> _SigmaTerms:
    """The terms of a grade and site: the three last asked for kept by identity (a record asks for the datasheet's and
    the measured grade's, the consistency check for the measured one with the datasheet's bias, and the measured
    one changes at every noise verdict), the site's part cached."""
    global _recent_terms
    for recent in _recent_terms:
        if grade is recent[0] and lat == recent[1] and gravity == recent[2]:
            return recent[3]
    bias, w_cos, cos_lat = _bias_terms(grade.acc_bias_ms2, grade.gyro_bias_rad_s, lat, gravity)
    vrw2, arw2, bounded = grade.acc_vrw_ms_rts**2, grade.gyro_arw_rad_rts**2, grade.base_motion_m_rts**2
    # a least-squares fit of the α history over (t, t²): white accelerometer noise of density q = VRW² leaves
    # Var(δψ) = 12 q / (g Ω cos L)² / T³ and Var(δθ) = 4 q / (g² T); a gyro walk Var(δψ) = 1.2 N² / (Ω cos L)² / T and
    # Var(δθ) = N² T / 3; white noise of density S in α itself Var(δψ) = 320 S / (g Ω cos L)² / T⁵ and
    # Var(δθ) = 3 S / (g² T³)
    kernel = np.array([12.0 * vrw2 / (gravity * w_cos) ** 2, 1.2 * arw2 / w_cos**2,
                       320.0 * bounded / (gravity * OMEGA_IE * cos_lat) ** 2, bias[0] ** 2, grade.gyro_bias_rad_s,
                       bias[1] ** 2, 4.0 * vrw2 / gravity**2, arw2 / 3.0, 3.0 * bounded / gravity**2])
    kernel.flags.writeable = False
    terms = _SigmaTerms(bias, kernel)
    _recent_terms = ((grade, lat, gravity, terms), *_recent_terms[:-1])
    return terms


def coarse_sigma_terms(grade: SensorGrade, lat: float, gravity: float) -> np.ndarray:
    """The coarse σ model's terms of a grade and site (read-only), as the compiled model takes them
    (:class:`_SigmaTerms`): what the fixed base's compiled hand-over test is given."""
    return _sigma_terms(grade, lat, gravity).kernel


@functools.lru_cache(maxsize=64)
def _bias_terms(acc_bias_ms2: float, gyro_bias_rad_s: float, lat: float,
                gravity: float) -> tuple[tuple[float, float], float, float]:
    """The bias limit (heading, level) in rad of these biases at this site, Ω cos L and cos L."""
    heading = np.hypot(np.tan(lat) * acc_bias_ms2 / gravity, gyro_bias_rad_s / (OMEGA_IE * np.cos(lat)))
    return (float(heading), acc_bias_ms2 / gravity), OMEGA_IE * np.cos(lat), np.cos(lat)


_recent_terms: tuple = ((None, np.nan, np.nan, None),) * 3


def inertial_alignment_sigma(grade: SensorGrade, lat: float, gravity: float, elapsed_s: float) -> AttitudeSigma:
    """1-sigma error of inertial-frame coarse alignment after ``elapsed_s`` seconds.

    Bias part (the bias limit with 1-sigma biases) plus the noise part of a least-squares fit
    of the α history: in the north channel α_N(t) = g t δθ + ½ g Ω cos L t² δψ + noise, so a
    white accelerometer noise of density q = VRW² leaves Var(δψ) = 12 q / (g Ω cos L)² / T³ and
    Var(δθ) = 4 q / (g² T), while a gyro random walk gives Var(δψ) = 1.2 N² / (Ω cos L)² / T.
    The gyro bias also tilts the integrated body attitude by ε T on every axis. The noise
    variances are scaled by the measured efficiency of the recursive estimator. What depends on the
    grade and site alone is computed once per grade (it runs at every record and motion check).
    """
    T = float(elapsed_s)
    if T <= 0.0:
        return AttitudeSigma(SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG)
    heading2, level2 = _inertial_alignment_variances(grade, lat, gravity, T)
    return AttitudeSigma(min(math.sqrt(heading2) / DEG, SIGMA_UNKNOWN_DEG),
                         min(math.sqrt(level2) / DEG, SIGMA_UNKNOWN_DEG))


def carried_sigma(sigma: AttitudeSigma, grade: SensorGrade, carried_s: float) -> AttitudeSigma:
    """1-sigma error (degrees, capped at the unknown angle's) of an attitude with ``sigma`` carried on by the gyros
    for ``carried_s`` seconds: every axis drifts by the gyro bias times the time and walks by the angle random walk.
    It is what a fixed-base estimate frozen before the base moved is worth later, and it grows fast on gyros whose
    bias the data showed far beyond the datasheet's (a rate in °/s read as rad/s)."""
    drift2 = ((grade.gyro_bias_rad_s * carried_s) ** 2 + grade.gyro_arw_rad_rts**2 * carried_s) / DEG**2
    return AttitudeSigma(min(math.sqrt(sigma.heading_deg**2 + drift2), SIGMA_UNKNOWN_DEG),
                         min(math.sqrt(sigma.level_deg**2 + drift2), SIGMA_UNKNOWN_DEG))


def inertial_alignment_sigmas(grade: SensorGrade, lat: float, gravity: float, elapsed_s: np.ndarray) -> np.ndarray:
    """The root sum of squares of the heading and level σ of :func:`inertial_alignment_sigma` (degrees) at each of
    the alignment times ``elapsed_s`` (s, all positive), in one pass."""
    heading2, level2 = _inertial_alignment_variances(grade, lat, gravity, elapsed_s)
    return np.hypot(np.minimum(np.sqrt(heading2) / DEG, SIGMA_UNKNOWN_DEG),
                    np.minimum(np.sqrt(level2) / DEG, SIGMA_UNKNOWN_DEG))


def _inertial_alignment_variances(grade: SensorGrade, lat: float, gravity: float,
                                  T: float | np.ndarray) -> tuple[float | np.ndarray, float | np.ndarray]:
    """(heading², level²) in rad² of :func:`inertial_alignment_sigma` after T (s: a float, or an array of them): the
    compiled model (``_policy.pxi``), which the fixed base's compiled hand-over test applies too."""
    kernel = _sigma_terms(grade, lat, gravity).kernel
    if np.ndim(T) == 0:
        return coarse_variances_one(kernel, ESTIMATOR_EFFICIENCY, float(T))
    return coarse_variances(kernel, ESTIMATOR_EFFICIENCY, np.ascontiguousarray(T, dtype=float).ravel())


def heading_noise_variances(grade: SensorGrade, lat: float, gravity: float, elapsed_s: float) -> tuple[float, float]:
    """The least-squares heading variances (rad²) after ``elapsed_s`` seconds from each noise alone: the
    accelerometer's white noise, 12 VRW² / (g Ω cos L)² / T³, and the gyro's angle random walk,
    1.2 N² / (Ω cos L)² / T (see :func:`inertial_alignment_sigma`)."""
    terms = _sigma_terms(grade, lat, gravity)
    T = float(elapsed_s)
    return terms.acc_heading / T**3, terms.gyro_heading / T


def auto_solver(grade: SensorGrade, lat: float, gravity: float, heading_sigma_deg: float) -> str:
    """The coarse solver for this datasheet ("auto"): "gls" where the gyro's angle random walk dominates the heading
    noise by the time that noise is down to ``heading_sigma_deg``, "opreq" where the accelerometer's white noise does.

    OPREQ cannot weigh a walk (its errors are the same growing tilt in every later vector) and stays above the walk's
    floor; GLS whitens it and sits on the floor, but moves more where white noise dominates (docs/results.md,
    "GLS"). The two
    variances of :func:`heading_noise_variances` are equal at T× = √(10 q) / (N g) and both fall with T, the
    accelerometer's faster: the walk dominates at the threshold if the noise σ at T× is still above it.
    """
    crossing_s = np.sqrt(10.0) * grade.acc_vrw_ms_rts / (grade.gyro_arw_rad_rts * gravity)
    sigma_at_crossing = np.sqrt(ESTIMATOR_EFFICIENCY * sum(heading_noise_variances(grade, lat, gravity, crossing_s)))
    return "gls" if sigma_at_crossing > heading_sigma_deg * DEG else "opreq"
