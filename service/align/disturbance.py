"""Motion that breaks the fixed-base model: a base that translates (docs/algorithms/disturbance.md).

Inertial-frame alignment of a base fixed in position explains α(t) = C_{b0}^{n0} β(t) with a
constant C_{b0}^{n0}: rotation of any kind (swing, a knock, turning on the spot) is carried by
C_b^{b0} and never shows. A base that translates adds its velocity change to α and nothing to β,
so under an estimate of C_{b0}^{n0} the horizontal part of C_{b0}^{n0} Δα − Δβ between two
instants is the velocity the base gained between them: a few mm/s for a rocking car or a moored
base, metres per second within seconds for a driven one.

:class:`MotionMonitor` watches that velocity at every check:

- **still**: the velocity gained over the last ``window_s``, under the estimate of ``window_s``
  ago (so that the fit has not bent itself around the new motion), stays below the threshold
  (above a quarter of it, with the estimate's heading moving by more than 2σ over the window, the
  base is ``suspect``: the pipeline withholds ``converged``);
- **moving**: it passed the threshold. The estimate of the window's start is frozen as the
  trusted attitude (the gyros carry it on), and the velocity gained since the window's start is
  tracked under it, with its drift bound (the trusted tilt times g times the time, its heading
  times the turn of the reference vector);
- **stopped**: the base has been at rest for ``settle_s``: no velocity gained over a window, and
  the velocity since the motion began back inside its drift bound. If the velocity ever left
  twice the threshold plus that bound the base really went somewhere and the alignment starts
  over; a jolt that came back within it is consistent with the alignment, which is kept.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._kernels import horizontal_gained, store_and_gain
from .conventions import misalignment
from .earth import Site

SUSPECT_FRACTION = 0.25
"""A base that gains more than this fraction of the threshold over a window, while the estimate's heading moves
by more than ``SUSPECT_SIGMAS`` of its σ over the same window, may be starting to move: a gyrocompass reads a
velocity as heading (0.06 m/s a minute into a drive-off turns it by 0.4°, σ 0.07°), so nothing is reported
converged until the motion is confirmed or the estimate holds still again. A person climbing into a parked car
moves it by a few cm/s, which late in an alignment turns the heading by far less than its σ."""
SUSPECT_SIGMAS = 2.0
DRIFT_SIGMAS = 3.0
"""The drift bound of the tracked velocity, in standard deviations of the trusted attitude's error."""


@dataclass(slots=True)
class MotionEpisode:
    """A base known to move: since ``start_s`` (elapsed time of the window's start before the detection)."""

    start_s: float
    alpha_start: np.ndarray       # α (3,) m/s, b0 axes, at start_s
    beta_start: np.ndarray        # β (3,) m/s, n0 axes, at start_s
    C_b0_n0: np.ndarray           # the trusted estimate (3, 3), frozen at the detection
    heading_sigma_rad: float      # its 1-sigma errors at start_s
    level_sigma_rad: float
    detected_s: float
    speed_mps: float = 0.0        # |velocity gained since start_s| at the last check
    peak_mps: float = 0.0         # its largest value
    still_since_s: float | None = None


@dataclass(frozen=True, slots=True)
class MotionCheck:
    """What one check found: ``state`` "moving" (detected now or still moving) or "stopped" (an episode ended),
    the speed (m/s: gained over the window at a detection, since the motion began afterwards, the peak at the end),
    and at the end whether the data contradict the alignment (``restart``)."""

    state: str
    speed_mps: float
    restart: bool = False


class MotionMonitor:
    """Checks, every ``check_interval_s`` of alignment time, whether a base meant to stay in place translates.

    site : the fixed site (its β and the navigation frame's turn, in closed form).
    threshold_mps : horizontal velocity gained over ``window_s`` that means "moving" (m/s).
    gyro_bias_rad_s : the datasheet's gyro bias. It tilts the integrated body attitude by ε t, which the estimate
        cannot follow: g ε t of acceleration in the residual, a velocity gained over a window that grows with the
        alignment's time, g ε t W. The threshold is raised by :data:`DRIFT_SIGMAS` of it (``drift_mps_per_s`` per
        second of alignment), so that a tactical or MEMS IMU on a still base is not taken for a moving one: 1°/h
        gains 0.06 m/s in 2 s after 10 minutes. A navigation-grade gyro's share is a few mm/s.
    """

    def __init__(self, site: Site, threshold_mps: float, window_s: float, check_interval_s: float,
                 settle_s: float, gyro_bias_rad_s: float = 0.0) -> None:
        self._lat, self._gravity = site.lat, site.gravity
        self.threshold_mps = threshold_mps
        self.drift_mps_per_s = DRIFT_SIGMAS * site.gravity * gyro_bias_rad_s * window_s
        self.settle_s = settle_s
        self._n = max(1, round(window_s / check_interval_s))
        self._elapsed = np.full(self._n + 1, np.nan)
        self._alpha = np.zeros((self._n + 1, 3))
        self._beta = np.zeros((self._n + 1, 3))
        self._C = np.zeros((self._n + 1, 3, 3))
        self.ring_count = 0
        """Checks stored in the ring since it last started (the slot of the next is this modulo its length)."""
        self.episode: MotionEpisode | None = None
        self.window_speed_mps = 0.0
        """The horizontal velocity gained over the last window at the last check (m/s; 0 until the window fills)."""
        self.suspect = False
        """The base may be starting to move (see :data:`SUSPECT_FRACTION`), as of the last check."""

    @property
    def suspect_line(self) -> tuple[float, float]:
        """A window's velocity above a + b·t (m/s, t the alignment's elapsed time in s) may be the base starting to
        move: (a, b), :data:`SUSPECT_FRACTION` of the threshold, which grows with the gyros' drift. The rule the
        compiled block loop stops at (_blocks.pyx) and :meth:`check` applies."""
        return SUSPECT_FRACTION * self.threshold_mps, SUSPECT_FRACTION * self.drift_mps_per_s

    @property
    def ring(self) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The checks' ring, for a compiled loop that stores its checks itself (_blocks.pyx): the window in checks n,
        and n + 1 slots of elapsed time (s), α and β (m/s, b0 and n0 axes) and C_b0^n0, written in place; with
        :attr:`ring_count` the whole state a check changes while the base is still."""
        return self._n, self._elapsed, self._alpha, self._beta, self._C

    def _gained(self, C_b0_n0: np.ndarray, elapsed_s: float, alpha: np.ndarray, beta: np.ndarray,
                alpha_from: np.ndarray, beta_from: np.ndarray) -> tuple[float, float]:
        """(|horizontal velocity gained| m/s, |horizontal turn of β| m/s) from the ``_from`` instant to now, in the
        navigation frame of now."""
        return horizontal_gained(self._lat, elapsed_s, C_b0_n0, alpha, beta, alpha_from, beta_from)

    def check(self, elapsed_s: float, alpha_b0: np.ndarray, C_b0_n0: np.ndarray,
              sigma_rad: Callable[[float], tuple[float, float]]) -> MotionCheck | None:
        """One check at ``elapsed_s``: α (3,) m/s (b0 axes) there, the current estimate C_b0^n0 and what gives the
        1-sigma (heading, level) errors (rad) of the estimate after a given elapsed time, asked only when the velocity
        calls for them (most checks find the base still without). None: the base stays still."""
        slot = self.ring_count % (self._n + 1)
        oldest = (self.ring_count + 1) % (self._n + 1)   # the entry one window ago, once the ring is full
        self.ring_count += 1
        episode = self.episode
        # the entry stored (β there computed), and with the window full and no episode its velocity gained
        speed = store_and_gain(self._lat, self._gravity, elapsed_s, alpha_b0, C_b0_n0, self._elapsed, self._alpha,
                               self._beta, self._C, slot, oldest, self.ring_count > self._n and episode is None)
        if self.ring_count <= self._n:
            return None
        if episode is None:
            self.window_speed_mps = speed
            # the heading's move over the window only once the velocity asks (a check every control step)
            threshold = self.threshold_mps + self.drift_mps_per_s * elapsed_s
            suspect_mps, suspect_mps_per_s = self.suspect_line
            self.suspect = speed > suspect_mps + suspect_mps_per_s * elapsed_s and (
                abs(misalignment(C_b0_n0, self._C[oldest])[2]) > SUSPECT_SIGMAS * sigma_rad(elapsed_s)[0])
            if speed <= threshold:
                return None
            # the estimate of the window's start is trusted with the σ it had then: 2 s into an alignment it is
            # worth a heading σ of 45°, not the 3° of the estimate at the detection
            start_s = float(self._elapsed[oldest])
            self.episode = MotionEpisode(start_s, self._alpha[oldest].copy(), self._beta[oldest].copy(),
                                         self._C[oldest].copy(), *sigma_rad(start_s), elapsed_s, speed, speed)
            return MotionCheck("moving", speed)
        beta = self._beta[slot]
        window_speed, _ = self._gained(episode.C_b0_n0, elapsed_s, alpha_b0, beta, self._alpha[oldest],
                                       self._beta[oldest])
        self.window_speed_mps = window_speed
        speed, turn = self._gained(episode.C_b0_n0, elapsed_s, alpha_b0, beta, episode.alpha_start,
                                   episode.beta_start)
        episode.speed_mps, episode.peak_mps = speed, max(episode.peak_mps, speed)
        drift = DRIFT_SIGMAS * (np.linalg.norm(alpha_b0 - episode.alpha_start) * episode.level_sigma_rad
                                + turn * episode.heading_sigma_rad)
        if window_speed >= 0.5 * self.threshold_mps or speed > self.threshold_mps + drift:
            episode.still_since_s = None
            return MotionCheck("moving", speed)
        if episode.still_since_s is None:
            episode.still_since_s = elapsed_s
        if elapsed_s - episode.still_since_s < self.settle_s:
            return MotionCheck("moving", speed)
        self.episode = None
        self.window_speed_mps, self.suspect = 0.0, False
        self.ring_count = 0   # the window starts afresh: the next detection compares with data after the rest
        return MotionCheck("stopped", episode.peak_mps, restart=episode.peak_mps > 2.0 * self.threshold_mps + drift)
