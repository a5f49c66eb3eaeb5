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
"""
from __future__ import annotations

import numpy as np

from .conventions import EYE3, cross, dcm_from_quat
from .earth import earth_turn_integrals

N_PARAMS = 12   # b, c, a (3 each) and ∇ (3)
RIDGE = 1e-12   # on the equilibrated normal matrix: keeps the first, rank-deficient solves finite
_RIDGE_I = RIDGE * np.eye(N_PARAMS)
_RIDGE_I.flags.writeable = False
_STEP_ROWS = EYE3[None, :, None, :]   # broadcasts each basis increment ΔP_i onto its I block of the design rows


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
        of solves, so the bits do not depend on how the observations are grouped.
        """
        if len(elapsed_s) == 0:
            return alpha.copy()
        C = dcm_from_quat(q_b_b0)
        basis = earth_turn_integrals(elapsed_s)
        t_last, basis_last, alpha_last, C_last, M_last = self._last
        dt = np.diff(elapsed_s, prepend=t_last)
        dM = 0.5 * dt[:, None, None] * (np.concatenate((C_last[None], C[:-1])) + C)
        M = _running_sum(M_last, dM)
        # the rows of each increment's design matrix [ΔP1 I, ΔP2 I, ΔP3 I, ΔM] (M, 3, 12)
        step = np.diff(basis, axis=0, prepend=basis_last[None])
        X = np.concatenate((step[:, None, :, None] * _STEP_ROWS, dM[:, :, None, :]),
                           axis=2).reshape(-1, 3, N_PARAMS)
        dalpha = np.diff(alpha, axis=0, prepend=alpha_last[None])
        weight = 1.0 / np.maximum(self._vrw2 * dt, 1e-300)   # observations are strictly later than the last
        XtX = sum(X[:, r, :, None] * X[:, r, None, :] for r in range(3))
        Xtz = sum(X[:, r, :] * dalpha[:, r, None] for r in range(3))
        normal = _running_sum(self.normal, weight[:, None, None] * XtX)
        rhs = _running_sum(self.rhs, weight[:, None] * Xtz)
        self.normal, self.rhs = normal[-1], rhs[-1]
        self._last = (float(elapsed_s[-1]), basis[-1], alpha[-1].copy(), C[-1], M[-1])
        params = _solve(normal, rhs)
        self.params = params[-1]
        return alpha - _swing_term(M, basis, _earth_axis(params, self._lat_sign), params[:, 9:])

    def earth_axis_b0(self) -> np.ndarray | None:
        """The Earth axis in b0 axes, w = C_{n0}^{b0} u (unit), from the fit: c = w × b; None before a fit."""
        w = _earth_axis(self.params[None], self._lat_sign)[0]
        return None if not w.any() else w


def _solve(normal: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The parameters (K, 12) of K normal systems (K, 12, 12), (K, 12), equilibrated (the unknowns' scales differ by
    orders of magnitude) with a ridge that keeps the first, rank-deficient ones finite."""
    scale = 1.0 / np.sqrt(np.maximum(np.diagonal(normal, axis1=1, axis2=2), 1e-300))
    scaled = normal * scale[:, :, None] * scale[:, None, :] + _RIDGE_I
    return scale * np.linalg.solve(scaled, (scale * rhs)[:, :, None])[:, :, 0]


def _running_sum(start: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """start + steps[0], start + steps[0] + steps[1], …: added one at a time, left to right."""
    if len(steps) == 1:   # the live path's one observation: the same single addition, without cumsum's cost
        return (start + steps[0])[None]
    return np.cumsum(np.concatenate((start[None], steps)), axis=0)[1:]


def _earth_axis(params: np.ndarray, lat_sign: float) -> np.ndarray:
    """w (…, 3) from the fitted b, c of ``params`` (…, 12): c = w × b, |w| = 1, the sign of the latitude settling
    its part along b. 0 where there is no fit (b = 0, or a fit of data that leave w undefined)."""
    b, c = params[..., 0:3], params[..., 3:6]
    b2 = np.sum(b * b, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        along = lat_sign * np.sqrt(np.maximum(0.0, 1.0 - np.sum(c * c, axis=-1, keepdims=True) / b2))
        w = cross(b, c) / b2 + along * b / np.sqrt(b2)
        w = w / np.sqrt(np.sum(w * w, axis=-1, keepdims=True))
    return np.where(np.isfinite(w).all(axis=-1, keepdims=True), w, 0.0)


def _swing_term(M: np.ndarray, basis: np.ndarray, w: np.ndarray, nabla: np.ndarray) -> np.ndarray:
    """D(t)∇̂ = M(t)∇̂ − E_b0(t)∇̂ (…, 3), with E_b0(t) = C_{n0}^{b0} E(t) C_{b0}^{n0} = P1 I + P2 [w×] + P3 w wᵀ the part
    of M(t) a static base has (w = 0 before a fit: ∇̂ is 0 then as well). Written out
    elementwise, not as matmuls: the same bits whatever the number of observations."""
    n0, n1, n2 = nabla[:, 0, None], nabla[:, 1, None], nabla[:, 2, None]
    along = w[:, 0, None] * n0 + w[:, 1, None] * n1 + w[:, 2, None] * n2
    static = basis[:, 0, None] * nabla + basis[:, 1, None] * cross(w, nabla) + basis[:, 2, None] * (along * w)
    return M[:, :, 0] * n0 + M[:, :, 1] * n1 + M[:, :, 2] * n2 - static
