"""The accelerometer bias seen through a swinging body: estimated and taken out of α (fixed site, seed 000).

An accelerometer bias ∇ is fixed in body axes. On a static base it turns with the Earth like gravity does,
and the attitude fit takes it as a tilt: the level and heading limits (docs/algorithms/coarse.md, "Accuracy
limits"). On a
swinging base it also turns with the swing, and its integral in α(t) = ∫ C_b^{b0} f^b dτ gains a term
D(t) ∇, D(t) the part of M(t) = ∫ C_b^{b0} dτ that a static base does not have: bounded, but with a
non-zero mean (a swing that starts at its centre integrates to (1 − cos ωt)/ω). The fit takes that term
as heading early on and walks it off slowly (seed-000 swing, bias alone: 0.008° above the limit at
100 s, 0.0017° at 200 s).

The term is linear in ∇ and the gyros give D(t), so ∇ can be estimated and the term removed, leaving the
static part (the limit) as it is. On a fixed site, with E(t) = ∫_0^t C_{n}^{n0} dτ and b0 axes,

    α(t) = C_{n0}^{b0} E(t) x + M(t) ∇,

where x = g·Up plus the static part of the bias. E(t) = P1 I + P2 [u×] + (t − P1) u uᵀ with P1 = sin(Ωt)/Ω,
P2 = (1 − cos Ωt)/Ω and u the Earth axis, so the first term is P1 b + P2 c + (t − P1) a with free vectors
a, b, c: a linear model with 12 unknowns that needs no attitude. Its increments between observations carry
white accelerometer noise (VRW² Δt per axis), and a least-squares fit with the datasheet bias as prior on ∇
keeps O(1) sums. On a static base M(t) is the static term itself, the data say nothing of ∇ and the
prior keeps ∇̂ at 0: nothing changes there.

The correction needs the Earth axis in b0, w = C_{n0}^{b0} u, for the static part E_b0(t) = P1 I +
P2 [w×] + (t − P1) w wᵀ of M(t); c = w × b gives it from the fit (the sign of the latitude settles the
component along b). Its error enters only through Ω t², so an early, rough w costs nothing.
M(t) is integrated by the trapezoid rule at the observation instants: the error is (ω Δt)²/12 of the
swing's part (0.2 % for a 0.2-Hz swing and 0.1-s observations).

The fit's noise is the accelerometer's alone. A swing's D(t) turns within seconds, where the gyro's walk and bias
barely tilt C_b^{b0}; a body that turns about the vertical (a turntable, a vehicle turning in place) spreads D(t)
over minutes, where they are the larger error, and ∇̂ ran to three times the true bias (0.2°/s, navigation grade:
1° of heading under σ 0.1°). So the fit takes no observation once the body has turned :data:`TURNED_DEG` about the
vertical from its start; ∇̂ stays as it was and the correction goes on with it, and the σ term of a turning body
(:mod:`.turning_bias`) holds what the bias then does.
"""
from __future__ import annotations

import numpy as np

from ._kernels import earth_axis, swing_corrected, swing_normal_equations

N_PARAMS = 12   # b, c, a (3 each) and ∇ (3)
RIDGE = 1e-12   # on the equilibrated normal matrix: keeps the first, rank-deficient solves finite (_kernels.pyx)
TURNED_DEG = 15.0
"""A body turned this far about the vertical from its start (deg) no longer swings about a steady mean: the fit holds
(module docstring). Above a yaw swing's ±5° seen from any phase of it, and the Earth's 15°/h sin L."""


class SwingBias:
    """Recursive estimate of the body-axis accelerometer bias ∇ from α and C_b^{b0}, and α with D(t)∇̂ removed.

    Parameters
    ----------
    lat : latitude (rad); its sign fixes the Earth axis' component along gravity.
    acc_bias_ms2 : 1-σ prior of each axis of ∇ (m/s², the datasheet's).
    acc_vrw_ms_rts : velocity random walk (m/s/√s): the noise of the α increments.

    State updates assign new arrays (never write into old ones), so a shallow copy runs ahead independently.
    """

    def __init__(self, lat: float, acc_bias_ms2: float, acc_vrw_ms_rts: float) -> None:
        self._lat_sign = float(np.sign(lat))
        self._vrw2 = acc_vrw_ms_rts**2
        self.normal = np.zeros((N_PARAMS, N_PARAMS))
        self.normal[9:, 9:] = np.eye(3) / acc_bias_ms2**2
        self.rhs = np.zeros(N_PARAMS)
        self.params = np.zeros(N_PARAMS)
        self.held = False   # the body has turned: ∇̂ is held where it was
        # at the last observation: t, E(t)'s integrals, α, C_b^{b0}, M
        self._last = (0.0, np.zeros(3), np.zeros(3), np.eye(3), np.zeros((3, 3)))

    @property
    def nabla(self) -> np.ndarray:
        """∇̂ (3,) m/s², body axes."""
        return self.params[9:]

    def correct(self, elapsed_s: np.ndarray, alpha: np.ndarray, q_b_b0: np.ndarray) -> np.ndarray:
        """α (M, 3) m/s at successive observations, ``elapsed_s`` (M,) s after the start, attitude C_b^{b0} as
        quaternions (M, 4): fold each into the fit, then return it with D(t)∇̂ removed (the fit up to it).

        All M observations at once: running sums (sequential, as one at a time would add them) and a stack
        of solves, so the bits do not depend on how the observations are grouped. The sums and the correction are
        compiled (_kernels.pyx: the trapezoid M(t), the weighted normal equations of the increments, equilibrated
        with the ridge; then D(t)∇̂), the solve is numpy's.
        """
        if len(elapsed_s) == 0:
            return alpha.copy()
        fitted = 0 if self.held else _before_turned(alpha, q_b_b0)
        self.held = fitted < len(elapsed_s)
        M_parts, basis_parts, params_parts = [], [], []
        for part, fits in ((slice(0, fitted), True), (slice(fitted, len(elapsed_s)), False)):
            if part.start == part.stop:
                continue
            t_last, basis_last, alpha_last, C_last, M_last = self._last
            scaled, scaled_rhs, scale, M, basis, C, normal, rhs = swing_normal_equations(
                elapsed_s[part], q_b_b0[part], alpha[part], self._vrw2, t_last, basis_last, alpha_last, C_last,
                M_last, self.normal, self.rhs, RIDGE)
            self._last = (float(elapsed_s[part][-1]), basis[-1], alpha[part][-1].copy(), C, M[-1])
            if fits:
                self.normal, self.rhs = normal, rhs
                # the one step left to numpy: LAPACK's solve, whose bits a hand-written elimination would not repeat
                params = scale * np.linalg.solve(scaled, scaled_rhs[:, :, None])[:, :, 0]
                self.params = params[-1]
            else:   # a turned body: ∇̂ held (module docstring), M(t) still followed for the correction
                params = np.broadcast_to(self.params, (len(M), N_PARAMS))
            M_parts.append(M)
            basis_parts.append(basis)
            params_parts.append(params)
        M, basis, params = (np.concatenate(parts) for parts in (M_parts, basis_parts, params_parts))
        return swing_corrected(alpha, M, basis, params, self._lat_sign)

    def earth_axis_b0(self) -> np.ndarray | None:
        """The Earth axis in b0 axes, w = C_{n0}^{b0} u (unit), from the fit: c = w × b; None before a fit."""
        w = earth_axis(self.params, self._lat_sign)
        return None if not w.any() else w


def _before_turned(alpha: np.ndarray, q_b_b0: np.ndarray) -> int:
    """How many of the observations (α (M, 3) m/s, C_b^{b0} (M, 4)) come before the body has turned
    :data:`TURNED_DEG` about the vertical from its start: the twist of C_b^{b0} about α's direction (the mean up in
    b0 axes), 2 atan2(q_v · up, q_w)."""
    up = alpha / np.maximum(np.linalg.norm(alpha, axis=1), 1e-300)[:, None]
    twist = 2.0 * np.arctan2(np.einsum("ij,ij->i", q_b_b0[:, 1:], up), q_b_b0[:, 0])
    turned = np.flatnonzero(np.abs(np.remainder(twist + np.pi, 2.0 * np.pi) - np.pi) > np.radians(TURNED_DEG))
    return int(turned[0]) if len(turned) else len(alpha)
