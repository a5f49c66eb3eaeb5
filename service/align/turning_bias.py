"""What an accelerometer bias seen through a turning body does to the inertial-frame fit, as a σ term (fixed site).

On a base that does not turn on the Earth a constant accelerometer bias ∇ (body axes) enters α(t) = ∫ C_b^{b0} f^b dτ
as E_b0(t) ∇, the same form as gravity: the fit takes it as a tilt, and the bias limit holds it. A body that turns
(a turntable, a vehicle turning in place) adds D(t) ∇ with D(t) = M(t) − E_b0(t), M(t) = ∫_0^t C_b^{b0} dτ from the
gyros and E_b0(t) = C_{n0}^{b0} E(t) C_{b0}^{n0} the part a fixed body has (E(t) = P1 I + P2 [u×] + P3 u uᵀ,
:func:`~.earth.earth_turn_integrals`). About the vertical at a rate ω, D(t) ∇ ≈ ½ ω t² (Up × ∇) for ωt ≪ 1: the
form of the Earth-rate term ½ g Ω cos L t² δψ that carries the heading, so the fit reads a heading error of
ω |∇_h| / (g Ω cos L) (0.2°/s, 50 µg at L = 45°: 0.2°, three times the bias limit), which the datasheet's bias
limit does not hold. The swing-bias fit (:mod:`.swing_bias`) cannot take it out: over a turn the gyro's walk is the
larger error in what separates ∇ from the Earth's terms.

The fit's response to a disturbance d(t) of α (n0 axes) is taken as that of a least-squares fit of the tilt δθ and
heading δψ over (t, t²) on [0, T] (docs/algorithms/coarse.md, "Accuracy limits"):

    g δθ = 48 ∫t d / T³ − 60 ∫t² d / T⁴,     ½ g Ω cos L δψ = −60 ∫t d / T⁴ + 80 ∫t² d / T⁵,

so with d = D(t) ∇ and ∇ of 1-σ b on every axis, δψ and δθ are linear in ∇ through the running sums
S1 = Σ t D Δt and S2 = Σ t² D Δt (3 × 3, one column per body axis of ∇), and their variances are b² times the
squared norms of those rows. A static base has D = 0 and the term is nil; a swing of a few degrees adds to σ only in
the first tens of seconds, while the Earth's term is still small.

E_b0 needs the Earth axis in b0 axes, which the fit gives only as it goes; the sums are kept with E's scalar
integrals apart (Σ t M Δt and Σ t P_j Δt), and the Earth axis enters when σ is asked for, with the attitude of
that moment: the same sums however the observations come in calls.
"""
from __future__ import annotations

import math

import numpy as np

from ._kernels import turning_bias_rows
from .conventions import dcm_from_quat, skew
from .earth import OMEGA_IE, earth_turn_integrals


class TurningBiasTerm:
    """Running sums of D(t) over the fit's observations, and the σ term they give (module docstring).

    Parameters
    ----------
    lat : latitude (rad): the Earth axis in n0, u = [0, cos L, sin L] (ENU).
    gravity : local gravity (m/s²).

    State updates assign new arrays, so a shallow copy runs ahead independently.
    """

    def __init__(self, lat: float, gravity: float) -> None:
        u = np.array([0.0, math.cos(lat), math.sin(lat)])
        self._earth = np.stack((np.eye(3), skew(u), np.outer(u, u)))   # E(t) = P1 I + P2 [u×] + P3 u uᵀ
        self._gravity = gravity
        self._heading_gain = 2.0 / (gravity * OMEGA_IE * math.cos(lat))
        # at the last observation: t (s), C_b^{b0}, M (s), Σ t M Δt, Σ t² M Δt (3 × 3), Σ t P_j Δt, Σ t² P_j Δt (3,)
        self._last = (0.0, np.eye(3), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3), np.zeros(3))
        # the sums before and at each observation of the last call (times (K + 1,) s, then the four sums stacked):
        # a record between them takes the last at or before its time
        self._times = np.zeros(1)
        self._stacked = tuple(s[None] for s in self._last[3:])

    def observe(self, elapsed_s: np.ndarray, q_b_b0: np.ndarray) -> None:
        """Fold observations at ``elapsed_s`` (K,) s after the start with the body attitude C_b^{b0} as quaternions
        (K, 4): M(t) by the trapezoid rule between them, each weighted by its spacing. Sums run in order from the
        previous ones, so the bits do not depend on how observations are grouped into calls."""
        if len(elapsed_s) == 0:
            return
        t_last, C_last, M_last, tM_last, t2M_last, tP_last, t2P_last = self._last
        t = np.asarray(elapsed_s, dtype=float)
        C = dcm_from_quat(q_b_b0)
        dt = np.diff(t, prepend=t_last)
        previous = np.concatenate((C_last[None], C[:-1]))
        M = np.cumsum(np.concatenate((M_last[None], 0.5 * dt[:, None, None] * (C + previous))), axis=0)[1:]
        tdt, t2dt = t * dt, t * t * dt
        P = earth_turn_integrals(t)
        # each sum with the previous call's last in front: row 0 holds the sums before these observations
        tM = np.cumsum(np.concatenate((tM_last[None], tdt[:, None, None] * M)), axis=0)
        t2M = np.cumsum(np.concatenate((t2M_last[None], t2dt[:, None, None] * M)), axis=0)
        tP = np.cumsum(np.concatenate((tP_last[None], tdt[:, None] * P)), axis=0)
        t2P = np.cumsum(np.concatenate((t2P_last[None], t2dt[:, None] * P)), axis=0)
        self._times, self._stacked = np.concatenate(([t_last], t)), (tM, t2M, tP, t2P)
        self._last = (float(t[-1]), C[-1], M[-1], tM[-1], t2M[-1], tP[-1], t2P[-1])

    def variances(self, elapsed_s: float, C_b0_n0: np.ndarray, acc_bias_ms2: float) -> tuple[float, float]:
        """(heading², level²) in rad² that a 1-σ accelerometer bias of ``acc_bias_ms2`` (m/s², every axis) seen
        through the body's turns leaves in the fit after ``elapsed_s`` (s), the fit's attitude C_{b0}^{n0} =
        C_b^n(0) being ``C_b0_n0``: the sums of the last observation at or before that time."""
        T = float(elapsed_s)
        k = max(int(np.searchsorted(self._times, T, side="right")) - 1, 0)
        tM, t2M, tP, t2P = (s[k] for s in self._stacked)
        if T <= 0.0 or not tM.any():
            return 0.0, 0.0
        # C_{b0}^{n0} E_b0 = (P1 I + P2 [u×] + P3 u uᵀ) C_{b0}^{n0}: the Earth axis enters through the attitude
        heading2, tilt2 = turning_bias_rows(np.ascontiguousarray(C_b0_n0, dtype=float), tM, t2M, tP, t2P, self._earth,
                                            T, self._heading_gain, self._gravity)
        b2 = acc_bias_ms2**2
        return b2 * heading2, b2 * tilt2
