"""Whether a fixed base's attitude estimates agree with the σ they were reported with (docs/algorithms/disturbance.md,
"Estimates that contradict their σ").

Every σ the alignment reports says its attitude is within a few σ of the truth. Two estimates, at t1 and t2, can
both be so only if they differ by less than K (σ1 + σ2) (plus a floor, :data:`FLOOR_DEG`): if they differ by more,
one of them was off by more than K σ, and the data contradict the model the estimator rests on. A slice of rotation
lost between two samples does that: 20 ms of a swinging base missing put the heading 14° off under a σ of 0.05°,
reported converged, since every later vector is compared with the earlier ones through a body attitude turned by
the missing rotation. So does a turn the gyros did not measure, or a wrong rate or scale factor. Nothing estimated
from such data can be trusted; an alignment on the data after the contradiction can.

:class:`ConsistencyMonitor` keeps the estimate of C_{b0}^{n0} once every :data:`INTERVAL_S` of alignment for the
last :data:`LOOKBACK_S`, once it is reported converged (before, σ is a linear model's of an estimate still far
from linear: a recursive fit's first seconds), and compares each new one, converged or not, with all of them by
the angle of the rotation between the two (the gyros' body attitude does not move it: a swing or a turn on the
spot is carried by C_b^{b0}). σ is the root sum of squares of heading and level σ at each instant, as the current
figures give it (the noise the data showed included).
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

INTERVAL_S = 4.0
"""Alignment time (s) between two estimates kept and checked."""
LOOKBACK_S = 64.0
"""How far back (s) estimates are kept: a contradiction grows for minutes after a lost slice of rotation."""
CONTRADICTION_SIGMAS = 5.0
"""K: each of two estimates that differ by more than K (σ1 + σ2) may be off by K σ; one of them is."""
FLOOR_DEG = 0.01
"""An angle allowed whatever σ says: the estimator's own approximations move the estimate of an ideal sensor's data
(σ 1e-5°) by 1e-4° over a minute."""


class ConsistencyMonitor:
    """Estimates of C_{b0}^{n0} kept every :data:`INTERVAL_S` (:meth:`check`) and compared with the new one."""

    def __init__(self) -> None:
        slots = round(LOOKBACK_S / INTERVAL_S)
        self._q = np.zeros((slots, 4))           # the kept estimates, as quaternions q_b0^n0
        self._elapsed = np.full(slots, np.nan)   # their alignment times (s)
        self._count = 0
        self.next_s = INTERVAL_S
        """The alignment time (s) of the next check."""

    def check(self, elapsed_s: float, q_b0_n0: np.ndarray, sigma_now_deg: float,
              sigma_deg: Callable[[np.ndarray], np.ndarray], keep: bool) -> str | None:
        """Compare the estimate q_b0^n0 (4,) of ``elapsed_s`` (s of alignment), whose σ is ``sigma_now_deg``, with
        those kept, and keep it if ``keep`` (it was reported converged: σ small enough for its linear model, the
        data's noise checked). σ is the root sum of squares of the 1-sigma heading and level errors in degrees;
        ``sigma_deg(elapsed)`` gives it at each of an array of alignment times. The contradiction found (what to
        tell the operator), or None."""
        self.next_s = elapsed_s + INTERVAL_S
        kept = min(self._count, len(self._elapsed))
        found = self._contradiction(elapsed_s, q_b0_n0, kept, sigma_now_deg, sigma_deg) if kept else None
        if keep:
            slot = self._count % len(self._elapsed)
            self._q[slot], self._elapsed[slot] = q_b0_n0, elapsed_s
            self._count += 1
        return found

    def _contradiction(self, elapsed_s: float, q: np.ndarray, kept: int, sigma_now_deg: float,
                       sigma_deg: Callable[[np.ndarray], np.ndarray]) -> str | None:
        # the angle θ of the rotation between two unit quaternions: cos(θ/2) = |q_now · q_then|
        cos_half = np.abs(self._q[:kept] @ q)
        # σ then ≥ 0: only an angle beyond the floor and K σ now can be beyond K (σ then + σ now), and few are
        least_deg = FLOOR_DEG + CONTRADICTION_SIGMAS * sigma_now_deg
        candidates = np.flatnonzero(cos_half < math.cos(0.5 * math.radians(min(least_deg, 180.0))))
        if len(candidates) == 0:
            return None
        allowed_deg = least_deg + CONTRADICTION_SIGMAS * sigma_deg(self._elapsed[candidates])
        angle_deg = np.degrees(2.0 * np.arccos(np.minimum(cos_half[candidates], 1.0)))
        beyond = np.flatnonzero(angle_deg > allowed_deg)
        if len(beyond) == 0:
            return None
        k = beyond[0]
        return (f"the attitude estimate turned {angle_deg[k]:.3g}° in {elapsed_s - self._elapsed[candidates[k]]:.0f} "
                f"s where its σ allowed {allowed_deg[k]:.2g}° ({CONTRADICTION_SIGMAS:g} σ then and now): the data "
                "contradict the fixed-base model (samples lost, a turn the gyros did not measure, a wrong rate or "
                "scale factor)")
