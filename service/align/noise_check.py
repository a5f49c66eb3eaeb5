"""The noise the data show, from the residual of the fixed-base model itself (docs/algorithms/compass.md, "Honest σ";
docs/field-data.md, "The noise part of σ comes from the residual").

The heading of inertial-frame alignment comes from α(t) = C_{n0}^{b0} β(t) over minutes, so its error is set by
how the error of α behaves over seconds to minutes, not by what one increment carries. A sample-level meter reads
engine vibration, an RLG's dither, quantisation and rocking as sensor noise and leaves σ 50-100× too large: all of
those are bounded motion of α, which averages out of the heading as T⁻⁵, while white accelerometer noise (a random
walk of α) averages out as T⁻³ and a gyro's angle random walk (an integrated random walk of α) as T⁻¹.

Per lag τ the meter takes the mean of the residual α − Ĉ β over windows of τ and the third difference of those
means, D_τ (horizontal part, per axis): a Hadamard variance of α. Its mean square tells the three apart by how it
grows with the lag (the constants are the integrals of the stencil against each process, checked in the tests):

    E[D_τ²] = (8/3) q τ + (2/3) g² N² τ³ + 20 S / τ

with q the accelerometer's white-noise density squared (VRW², m²/s³), N the gyro's angle random walk (rad/√s) and
S the density of a bounded disturbance of α seen as white noise (m²/s: a variance times its correlation time; a
periodic one shorter than τ averages out of the window means as well). The stencil cancels the reference up to its
cubic term, so Ĉ takes out only the rest (gΩ²τ³, 2e-4 m/s at 16 s) and a rough estimate is enough. The lags run
from 1 s to 16 s; each lag's mean square is fitted with its statistical weight. σ takes the upper bound
(:data:`SIGNIFICANCE` standard errors) of the white noise and of the bounded disturbance, whatever the datasheet
says: too loud a datasheet gives way to the data, too quiet a one cannot make σ overconfident, and white noise far
under a quantiser's floor is bounded by what the floor lets through. The gyro's walk shows only at the longest lags,
too faintly to lower a datasheet's figure; it raises it where the data show it surely louder. A knock, a door
or a person climbing in is an outlier of the shortest lag against its running mean: the stencils that contain it
are left out. Memory is O(1).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._kernels import hadamard_feed, noise_figures
from .conventions import DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from .earth import OMEGA_IE
from .sensor_model import SMALLEST_FIGURE, SensorGrade

LAGS_S = (1.0, 2.0, 4.0, 8.0, 16.0)
STENCIL = np.array([1.0, -4.0, 6.0, -4.0, 1.0])
"""The fourth difference of the running sum of α: the third difference of its window means, newest first."""
MIN_SPAN_S = 10.0
"""Seconds of stencils a lag needs before its mean square is fitted; three lags are needed for a verdict."""
OUTLIER_FACTOR = 25.0
"""A shortest-lag square this many times its running mean is an event, not noise (χ² with 2 dof: p ≈ 1e-6)."""
MIN_OUTLIER_COUNT = 100
SETTLE_S = 2.0
"""Seconds after an event whose stencils are left out too (a knock rings down)."""
SIGNIFICANCE = 2.0
"""Standard errors by which the fit must differ from the datasheet's figure before it replaces it."""
VERDICT_STEPS = 10
"""The pipeline asks for a verdict every this many control steps (once a second of 0.1-s steps)."""
ALARM_FACTOR = 2.0
"""A density surely this many times the datasheet's (its lower bound) is worth telling the operator."""
MOMENTS = 23
"""The meter's running sums (Σ α, Σ β) and the moments of the residual's trend (Σ t α, Σ t β, Σ t² α, Σ t² β, Σ tᵏ
for k = 0..4): see :meth:`NoiseMeter.trend`."""
TREND_EVERY_STEPS = 100
"""Observations between two looks at the residual's trend (10 s at 0.1-s steps): it grows over minutes."""
MIN_TREND_S = 30.0
"""Seconds of observations before the trend is judged."""
BIAS_SIGMAS = 3.0
"""A datasheet's bias is a 1-σ figure per axis: a sensor's may be this many times it."""
TREND_SIGMAS = 4.0
"""The noise's share of the fitted trend allowed, in its standard deviations."""
SCALE_HINT_FACTOR = 10.0
"""A measured gyro bias beyond the Earth's rate in a gyro stated this many times better than it (one that can find
north) points the operator at the gyros' scale: their units or the time base (imu.rate_hz)."""
MIN_MEAN_SQUARE = 1e-100
"""(m/s)²: the least a lag's mean square weighs the fit as, so that a lag whose squares are all zero (a constant
signal) weighs finitely (its square would underflow to an infinite weight)."""


@dataclass(frozen=True, slots=True)
class NoiseFigures:
    """What the residual shows: q = VRW² (m²/s³), N² = ARW² (rad²/s), the bounded disturbance's density S (m²/s),
    each with its standard error."""

    q: float
    n2: float
    s: float
    q_se: float
    n2_se: float
    s_se: float


@dataclass(frozen=True, slots=True)
class NoiseVerdict:
    """The grade σ should use and what to tell the operator (None: nothing)."""

    grade: SensorGrade
    notice: str | None


class NoiseMeter:
    """Measures q, N² and S from the fixed-base residual, one α per observation.

    step_s : the observation interval (s). lat : site latitude (rad). gravity : m/s².
    """

    def __init__(self, step_s: float, lat: float, gravity: float) -> None:
        self.step_s = step_s
        self._lat, self._gravity = lat, gravity
        self._lags = np.array([max(1, round(lag / step_s)) for lag in LAGS_S], dtype=np.int64)
        self._lag_s = self._lags * step_s
        self._lag_cubed = self._lag_s**3   # once, by numpy's power: the fit's rows keep its bits
        self._capacity = 4 * int(self._lags.max()) + 1
        self._alpha_sum = np.zeros((self._capacity, 3))   # running sums of α and β, m/s (one term per step)
        self._beta_sum = np.zeros((self._capacity, 3))
        self._moments = np.zeros(MOMENTS)   # the running sums and the trend's moments (_noise_feed.pxi)
        self._sums = np.zeros(len(self._lags))
        self._counts = np.zeros(len(self._lags))
        self.steps = 0
        self.bad_until = -1   # the last step of the last event's span
        self.outliers = 0
        self.C_n0_b0: np.ndarray | None = None
        """The rough estimate that takes the reference's curvature out (None: left in, at the start)."""
        self.bias_rad_s = 0.0
        """The least gyro bias (rad/s) the residual's trend has shown beyond the datasheet's (0: none)."""
        self._trend_at = 0   # the step count of the last look at the trend

    def feed(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray) -> bool:
        """α (M, 3) m/s in b0 axes at M observations, ``elapsed_s`` (M,) after the start, in order; whether the step
        count passed a multiple of :data:`VERDICT_STEPS` (a verdict is due). The per-observation loop is compiled
        (``_kernels.hadamard_feed``): per observation the rings take the running sums of α and β, and once the
        shortest lag is ready each lag's stencil D_τ and its horizontal square are formed; a shortest-lag square
        :data:`OUTLIER_FACTOR` times its running mean marks an event, and the squares of every lag whose stencil
        reaches into an event's span are left out."""
        self.steps, self.bad_until, outliers, verdict_due = hadamard_feed(
            self._lat, self._gravity, np.ascontiguousarray(elapsed_s, dtype=float),
            np.ascontiguousarray(alpha_b0, dtype=float), self._alpha_sum, self._beta_sum, self._moments,
            self._lags, self._sums, self._counts, self.C_n0_b0, self.steps, self.bad_until,
            round(SETTLE_S / self.step_s), OUTLIER_FACTOR, MIN_OUTLIER_COUNT, VERDICT_STEPS)
        self.outliers += outliers
        return verdict_due

    @property
    def running_sums(self) -> tuple[np.ndarray, ...]:
        """The arrays the feed writes in place, for a compiled loop that feeds the meter itself (_blocks.pyx): the
        rings of α's and β's running sums (capacity, 3) m/s, the trend's moments, each lag's length in steps, and its
        sum of squares and count. With :attr:`steps` and :attr:`bad_until` they are the whole state a feed changes."""
        return self._alpha_sum, self._beta_sum, self._moments, self._lags, self._sums, self._counts

    def figures(self) -> NoiseFigures | None:
        """The fit of the lags with :data:`MIN_SPAN_S` of stencils; None before three lags have them. Each lag's
        mean square m is fitted by the model's row (8/3 τ, 2/3 g² τ³, 20 / τ) with its statistical weight: a mean
        square of n_eff independent χ² terms has variance 2 m² / n_eff, and overlapping stencils of one lag are
        independent about every other stencil length (n_eff = count × step / 2τ); x ≥ 0 of the weighted fit over its
        active sets. Compiled in one call (``_kernels.noise_figures``)."""
        fit = noise_figures(self._sums, self._counts, self._lag_s, self._lag_cubed, self.step_s, self._gravity,
                            MIN_SPAN_S, MIN_MEAN_SQUARE)
        return None if fit is None else NoiseFigures(*fit)

    def trend(self) -> tuple[float, float] | None:
        """The residual's trend over every observation, under the rough estimate: (the east part of the t²
        coefficient of C_b0^n0 α − β (m/s³, n0 axes), the span (s)); None without an estimate or 3 observations.

        A constant gyro bias tilts the integrated attitude at its rate. Its east part the fit takes as heading (the
        bias limit); its north part ε_N adds −½ g ε_N t² to the east residual, which no attitude can take (a tilt of
        the estimate is linear in t, a heading error turns the reference's east t² term north). So the east t²
        coefficient measures ε_N whatever the estimate's own error. The least-squares fit of c₀ + c₁ t + c₂ t² comes
        from the moments kept by the compiled loop; its normal matrix is scaled by the span so that hours of data
        stay well conditioned."""
        m = self._moments.tolist()
        count, t1 = m[18], m[19]
        if self.C_n0_b0 is None or count < 3:
            return None
        span_s = 2.0 * t1 / count   # observations from the start at a fixed step
        # the moments of u = t / span: the normal matrix [[s0, s1, s2], [s1, s2, s3], [s2, s3, s4]] and the east
        # residual's [r0, r1, r2]; c₂ of t is the last unknown of u over span², by Cramer's rule
        s0, s1, s2, s3, s4 = (m[18 + k] / span_s**k for k in range(5))
        east_b0 = self.C_n0_b0[:, 0].tolist()   # the n0 east axis in b0: C_b0^n0's first row
        r0, r1, r2 = (sum(e * a for e, a in zip(east_b0, m[6 * k:6 * k + 3], strict=True)) - m[6 * k + 3]
                      for k in range(3))
        r1, r2 = r1 / span_s, r2 / span_s**2
        det = s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2) + s2 * (s1 * s3 - s2 * s2)
        if not det > 0.0:
            return None
        c2_u = (s0 * (s2 * r2 - r1 * s3) - s1 * (s1 * r2 - r1 * s2) + r0 * (s1 * s3 - s2 * s2)) / det
        return c2_u / span_s**2, span_s

    def _judge_bias(self, stated: SensorGrade, figures: NoiseFigures, heading_sigma_rad: float) -> None:
        """Raise :attr:`bias_rad_s` to the north gyro bias the residual's trend shows (:meth:`trend`), if it is surely
        beyond what the datasheet's biases and the noise can make of it: the datasheet's figure then understates
        every axis's, the east one's that sets the heading's limit too. The trend's standard deviation from the
        noise, for a fit of a quadratic over a span T: 180 S / T⁵ (a bounded disturbance of α), 30/7 q / T³ (white
        accelerometer noise: α walks) and 5/14 g² N² / T (the gyro's walk: α's error is its integral). The estimate's
        heading error δψ (``heading_sigma_rad`` its σ) leaves ½ g Ω cos L δψ² of the reference's east t² term."""
        found = self.trend()
        if found is None or found[1] < MIN_TREND_S:
            return
        c2, span_s = abs(found[0]), found[1]
        g = self._gravity
        noise = math.sqrt(180.0 * max(figures.s, 0.0) / span_s**5 + 30.0 / 7.0 * max(figures.q, 0.0) / span_s**3
                          + 5.0 / 14.0 * g * g * max(figures.n2, 0.0) / span_s)
        # the north gyro at the stated bias, and an accelerometer's bias turning with the Earth
        stated_c2 = 0.5 * (g * stated.gyro_bias_rad_s + OMEGA_IE * stated.acc_bias_ms2)
        estimate = 0.5 * g * OMEGA_IE * math.cos(self._lat) * (TREND_SIGMAS * heading_sigma_rad) ** 2
        if c2 > BIAS_SIGMAS * stated_c2 + TREND_SIGMAS * noise + estimate:
            self.bias_rad_s = max(self.bias_rad_s, 2.0 * (c2 - TREND_SIGMAS * noise) / g)

    def verdict(self, stated: SensorGrade,
                heading_sigma_rad: Callable[[], float] | None = None) -> NoiseVerdict | None:
        """The grade σ should use: the datasheet's, with each density the data tell apart from it replaced by the
        data's, the bounded disturbance they show, and a gyro bias the residual's trend shows surely larger (judged
        when ``heading_sigma_rad`` gives the rough estimate's heading σ, asked every :data:`TREND_EVERY_STEPS`);
        None before the meter has figures."""
        f = self.figures()
        if f is None:
            return None
        if heading_sigma_rad is not None and self.steps - self._trend_at >= TREND_EVERY_STEPS:
            self._trend_at = self.steps
            self._judge_bias(stated, f, heading_sigma_rad())
        # the white noise and the bounded disturbance are measured at these lags, and an overconfident σ is the
        # worse failure: σ takes their upper bounds, whatever the datasheet says; the gyro's walk shows only at the
        # longest lags, too faintly to lower a datasheet's figure: it raises it where the data show it surely louder
        q = f.q + SIGNIFICANCE * f.q_se
        n2 = max(stated.gyro_arw_rad_rts**2, f.n2 if f.n2 > SIGNIFICANCE * f.n2_se else 0.0)
        bounded = f.s + SIGNIFICANCE * f.s_se
        # (the figures are ≥ 0: math's square root is numpy's, correctly rounded; the grade built directly, as
        # dataclasses.replace would, without its look at the fields)
        grade = SensorGrade(max(stated.gyro_bias_rad_s, self.bias_rad_s), max(math.sqrt(n2), SMALLEST_FIGURE),
                            stated.acc_bias_ms2, max(math.sqrt(q), SMALLEST_FIGURE), math.sqrt(bounded))
        parts = []
        if self.bias_rad_s > stated.gyro_bias_rad_s:
            parts.append(f"a gyro bias of at least {self.bias_rad_s / DH_TO_RS:.3g}°/h, "
                         f"{self.bias_rad_s / stated.gyro_bias_rad_s:.3g}× the datasheet's "
                         f"{stated.gyro_bias_rad_s / DH_TO_RS:.3g}°/h (gyro_bias_deg_h)")
        if grade.gyro_arw_rad_rts > ALARM_FACTOR * stated.gyro_arw_rad_rts:
            parts.append(f"gyro noise {grade.gyro_arw_rad_rts / DRH_TO_RRS:.3g}°/√h, "
                         f"{grade.gyro_arw_rad_rts / stated.gyro_arw_rad_rts:.3g}× the datasheet's "
                         f"{stated.gyro_arw_rad_rts / DRH_TO_RRS:.3g}°/√h (gyro_arw_deg_rth)")
        if f.q - SIGNIFICANCE * f.q_se > (ALARM_FACTOR * stated.acc_vrw_ms_rts) ** 2:   # surely louder
            parts.append(f"accelerometer noise {grade.acc_vrw_ms_rts / UG_TO_MS2:.3g} µg/√Hz, "
                         f"{grade.acc_vrw_ms_rts / stated.acc_vrw_ms_rts:.3g}× the datasheet's "
                         f"{stated.acc_vrw_ms_rts / UG_TO_MS2:.3g} µg/√Hz (acc_vrw_ug_rthz)")
        notice = (f"the data show {' and '.join(parts)}: σ uses the measured figure; check [sensor] or the log's "
                  "datasheet keys") if parts else None
        if self.bias_rad_s > OMEGA_IE > SCALE_HINT_FACTOR * stated.gyro_bias_rad_s:
            # a gyro stated fit to find north, wrong by more than the rate it finds north from
            notice += (f"; a gyro stated at {stated.gyro_bias_rad_s / DH_TO_RS:.3g}°/h that reads beyond the Earth's "
                       "rate (15.04°/h) is more likely read at the wrong scale: check the gyros' units and imu.rate_hz "
                       "(the time of an IMU stamped by its sample counter)")
        return NoiseVerdict(grade, notice)
