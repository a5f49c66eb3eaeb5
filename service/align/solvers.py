"""Attitude determination from vector pairs b = A r with a constant A (docs/algorithms/coarse.md).

All solvers keep O(1) state: the 4×4 Davenport matrix K, its weight m and the scalar trace of
the covariance P of K's error (Φ = I and isotropic Q make the traces enough for the gain).
They differ only in the gain ρ_k that blends a new observation into K:

- Optimal-REQUEST (Choukroun 2004, seed 000): ρ* = m² tr P / (m² tr P + δm² tr R);
- REQUEST: a fixed fading gain ρ;
- batch q-method (OBA): ρ_k = 1/(k+1), the equally weighted sum of every δK, streamed.

:class:`WhitenedWahba` ("gls") is the generalised least-squares solution of the same problem on a
fixed base: it fits the α increments, whitened for the noise they actually carry (the gyro's angle
random walk, the accelerometer's white noise, a bounded velocity disturbance), so every pair gets
the weight its information earns.

:class:`CentredWahba` ("centred") solves a different problem on the same pairs, unnormalised:
b_k = A r_k + c with an unknown constant c common to all pairs (Kabsch). Aided modes need it:
their α holds the first aiding sample V^b(0) (or V^n(0)) as such a constant, and one noisy
sample would otherwise tilt every pair alike (docs/algorithms/odometer.md, "Centred solver").

Matrix convention: K = [[S - σI, z], [zᵀ, σ]] with the vector part first; its top eigenvector
q̄ = [q_v, q_4] gives A(q̄) = (q_4² - q_v·q_v) I + 2 q_v q_vᵀ - 2 q_4 [q_v×]. With b in body
and r in navigation axes A = C_n^b, so the Hamilton quaternion of C_b^n is [q_4, q_v]
(``quaternion_from_K``, compiled: service/align/_attitude.pyx).
"""
from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import numpy as np

from ._attitude import quaternion_from_K
from ._kernels import recursive_k_fold, recursive_k_prepare
from .conventions import dcm_from_quat, skew

if TYPE_CHECKING:
    from .sensor_model import SensorGrade

SOLVERS = ("opreq", "request", "qmethod", "centred", "gls")
ALIGNMENT_SOLVERS = ("auto", *SOLVERS)
"""What ``alignment.solver`` takes: "auto" picks OPREQ or GLS from the datasheet (sensor_model.auto_solver)."""
_GAIN_POLICY = {"opreq": 0, "request": 1, "qmethod": 2}
"""The compiled fold's code of each recursive solver's gain (_kernels.recursive_k_fold)."""


def davenport(B: np.ndarray) -> np.ndarray:
    """Davenport matrices K (..., 4, 4) of attitude profile matrices B (..., 3, 3) = Σ w b rᵀ."""
    sigma = np.einsum("...ii->...", B)
    K = np.empty((*B.shape[:-2], 4, 4))
    K[..., :3, :3] = B + np.swapaxes(B, -1, -2) - sigma[..., None, None] * np.eye(3)
    z = np.stack((B[..., 1, 2] - B[..., 2, 1], B[..., 2, 0] - B[..., 0, 2], B[..., 0, 1] - B[..., 1, 0]), axis=-1)
    K[..., :3, 3] = z
    K[..., 3, :3] = z
    K[..., 3, 3] = sigma
    return K


def delta_K(b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Davenport matrices δK (M, 4, 4) of unit vector pairs b, r (M, 3), unit weight each."""
    return davenport(b[:, :, None] * r[:, None, :])


def request_noise(b: np.ndarray, r: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """R = E[V Vᵀ] (M, 4, 4) of the noise V of δK when E[δb δbᵀ] = μ (I - b bᵀ).

    V = δK(δb, r) is the Davenport matrix of the rank-one B = δb rᵀ, and such a matrix squares
    to |δb|² |r|² I₄; hence R = μ tr(I - b bᵀ) |r|² I₄ = 2μ I₄ for unit vectors, exactly (a test
    checks it against the sample covariance). The R11 block quoted after Choukroun (docs/algorithms/coarse.md,
    "Recursive K: REQUEST and Optimal-REQUEST") is not what this V gives; only tr R enters the gain, and there the two
    differ by a near-constant factor that cancels in ρ*.
    """
    scale = np.asarray(mu, dtype=float) * (3.0 - np.einsum("mi,mi->m", b, b)) * np.einsum("mi,mi->m", r, r)
    return scale[:, None, None] * np.eye(4)


class RecursiveK:
    """Recursive K-matrix attitude estimator with a selectable gain policy (see module docstring).

    Parameters
    ----------
    solver : "opreq", "request" or "qmethod".
    rho : the fixed fading gain of "request" (seed 000 compares 0.1, 0.01, 0.001).
    trace_Q : trace of the process noise added per observation (slow decorrelation; default 0).
    """

    def __init__(self, solver: str = "opreq", rho: float = 0.01, trace_Q: float = 0.0) -> None:
        if solver not in SOLVERS[:3]:
            raise ValueError(f"unknown solver {solver!r}; choose one of {', '.join(SOLVERS)}")
        if solver == "request" and not 0.0 < rho <= 1.0:
            raise ValueError(f"REQUEST gain rho must be in (0, 1], got {rho}")
        self.solver = solver
        self.fixed_rho = rho
        self.trace_Q = trace_Q
        self.K = np.zeros((4, 4))
        self.m = 0.0
        self.trace_P = np.inf
        self.rho = 1.0
        self.n_obs = 0
        self._q: np.ndarray | None = None   # the quaternion of K, once asked for (fold assigns None)

    def add(self, b: np.ndarray, r: np.ndarray, mu: np.ndarray) -> None:
        """Fold in M single-vector observations in time order.

        b, r : (M, 3) unit observation (body) and reference (navigation) vectors.
        mu : (M,) per-axis variance of each b (rad²), OPREQ's noise model.
        """
        self.fold(*self.prepare(b, r, mu))

    @staticmethod
    def prepare(b: np.ndarray, r: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(δK (M, 4, 4), tr R (M,)) of M observations, for :meth:`fold` (vectorised).

        b, r need not be unit vectors: each pair is normalised here (a unit weight each). Compiled (_kernels.pyx:
        the normalisation, :func:`delta_K` and the trace of :func:`request_noise`, the same bits).
        """
        return recursive_k_prepare(b, r, np.asarray(mu, dtype=float).reshape(-1))

    def fold(self, dK: np.ndarray, trace_R: np.ndarray) -> None:
        """Blend prepared observations into K one after the other: K ← a K + c δK.

        Strictly sequential, so K gets the same bits however the observations are grouped into
        calls (one per block live, many per chunk offline).
        """
        if len(trace_R) == 0:
            return
        self.K, self.m, self.trace_P, self.n_obs, self.rho = recursive_k_fold(
            self.K, np.ascontiguousarray(dK, dtype=float), np.ascontiguousarray(trace_R, dtype=float), self.m,
            self.trace_P, self.n_obs, self.rho, self.trace_Q, _GAIN_POLICY[self.solver], self.fixed_rho)
        self._q = None

    @property
    def known_quaternion(self) -> np.ndarray | None:
        """The quaternion of K if it has been solved for since the last fold (read-only), else None."""
        return self._q

    def load(self, K: np.ndarray, m: float, trace_P: float, n_obs: int, rho: float, q: np.ndarray | None) -> None:
        """The state a compiled loop over the folds left (_blocks.pyx): K, its weight, tr P, the pairs folded and the
        last gain, with the quaternion of K where the loop solved for it (None: not solved since its last fold)."""
        self.K, self.m, self.trace_P, self.n_obs, self.rho = K, m, trace_P, n_obs, rho
        if q is not None:
            q.flags.writeable = False
        self._q = q

    def quaternion(self) -> np.ndarray:
        """Current estimate of C_b^n(0) as [w, x, y, z] (read-only); identity before any observation. Solved once
        per fold: every record, σ and check between two observations asks for the same K's."""
        if self._q is None:
            self._q = np.array([1.0, 0.0, 0.0, 0.0]) if self.n_obs == 0 else quaternion_from_K(self.K)
            self._q.flags.writeable = False
        return self._q


class CentredWahba:
    """Least squares for b_k = A r_k + c with a free constant c, from O(1) running sums.

    B = Σ w b rᵀ − (Σ w b z ᵀ)(Σ w z zᵀ)⁻¹(Σ w r zᵀ)ᵀ over the unnormalised pairs, z = [1] (the constant
    c; with ``drift``, z = [1, s_k] and the fit also absorbs c₁ s_k for a known scalar s_k per pair);
    the attitude is the top eigenvector of B's Davenport matrix, like the other solvers. Same
    interface as :class:`RecursiveK` (``prepare``/``fold``/``quaternion``), so the coarse stage and
    the pipeline use either. ``rho`` and ``trace_P`` are reported as 1/n and NaN.

    offset : False drops the constant c (and the drift): plain weighted Wahba on unnormalised pairs.

    weighted : weight each pair by 1/μ, μ the variance ``prepare`` is given (else equal weights,
        μ ignored). A weighted fit's residual variance is then in units of the stated noise.
    drift : a second nuisance vector c₁ times the scalar ``s`` given to ``prepare`` per pair (the
        position formula's first-fix error over the span).
    gate_chi2 : screen each pair before it is added (GNSS glitches): a pair whose residual e against
        the fit so far, eᵀS⁻¹e with S its predicted covariance in units of the stated noise (the pair's,
        the offset estimate's and the fit's attitude error seen through the pair's reference), over the
        fit's residual variance per axis (at least 1: never tighter than the stated noise), exceeds this
        is left out and counted in ``rejected``. Active from :data:`GATE_MIN_PAIRS` pairs on, the fit's
        first residual degrees of freedom (None: no screening); after :data:`GATE_REOPEN_PAIRS`
        rejections in a row the next as many pairs are taken unscreened (counted in ``reopened``): a
        fit gone wrong, or a lasting change of the data, must not lock the data out for good.
    """

    solver = "centred"

    def __init__(self, weighted: bool = False, gate_chi2: float | None = None, drift: bool = False,
                 offset: bool = True) -> None:
        if gate_chi2 is not None and not weighted:
            raise ValueError("screening pairs needs their stated noise: weighted=True")
        self.weighted = weighted
        self.gate_chi2 = gate_chi2
        m = (2 if drift else 1) if offset else 0
        self.S_zz = np.zeros((m, m))   # Σ w z zᵀ, Σ w b zᵀ, Σ w r zᵀ: the nuisance terms' sums
        self.S_bz = np.zeros((3, m))
        self.S_rz = np.zeros((3, m))
        self.S_br = np.zeros((3, 3))
        self.S_rr = np.zeros((3, 3))   # Σ w r rᵀ and Σ w |b|²: the fit's residual and information (covariance)
        self.S_bb = 0.0
        self._G: np.ndarray | None = None   # (Σ w z zᵀ)⁺ of the sums as they are; None: not since they changed
        self.n_obs = 0
        self.rejected = 0
        self.reopened = 0
        self._rejected_in_row = 0
        self._unscreened_left = 0
        self.rho = 1.0
        self.trace_P = float("nan")

    def prepare(self, b: np.ndarray, r: np.ndarray, mu: np.ndarray, s: np.ndarray | None = None,
                offset: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(w b rᵀ (M, 3, 3), [b, r, w, z] (M, 7 + m)) of M pairs, for :meth:`fold`; ``s`` (M,) the drift
        regressor (with ``drift``). ``offset`` False: pairs that carry neither the constant nor the drift
        (b = A r exactly: z = 0), fitted together with those that do."""
        w = 1.0 / np.asarray(mu, dtype=float) if self.weighted else np.ones(len(b))
        m = len(self.S_zz)
        z = [np.ones(len(b))] * min(m, 1) + ([np.asarray(s, dtype=float)] if m == 2 else [])
        if not offset:
            z = [np.zeros(len(b))] * m
        return w[:, None, None] * b[:, :, None] * r[:, None, :], np.column_stack((b, r, w, *z))

    def fold(self, outer: np.ndarray, pairs: np.ndarray) -> None:
        """Add prepared pairs to the sums, one after the other (same bits however grouped)."""
        for k in range(len(pairs)):
            b, r, w, z = pairs[k, :3], pairs[k, 3:6], pairs[k, 6], pairs[k, 7:]
            if self._unscreened_left:
                self._unscreened_left -= 1
            elif self.gate_chi2 is not None and self.n_obs >= GATE_MIN_PAIRS and not self._consistent(b, r, w, z):
                if self._rejected_in_row < GATE_REOPEN_PAIRS:
                    self.rejected += 1
                    self._rejected_in_row += 1
                    continue
                self.reopened += 1
                self._unscreened_left = GATE_REOPEN_PAIRS - 1
            self._rejected_in_row = 0
            self.S_zz = self.S_zz + w * np.outer(z, z)
            self.S_bz = self.S_bz + w * np.outer(b, z)
            self.S_rz = self.S_rz + w * np.outer(r, z)
            self.S_br = self.S_br + outer[k]
            self.S_rr = self.S_rr + w * np.outer(r, r)
            self.S_bb = self.S_bb + w * float(b @ b)
            self._G = None
            self.n_obs += 1
        self.rho = 1.0 / max(self.n_obs, 1)

    @classmethod
    def from_pairs(cls, b: np.ndarray, r: np.ndarray) -> CentredWahba:
        """The solver holding the M pairs (M, 3) at once, equal weights (vectorised sums; offline batches)."""
        solver = cls()
        solver.S_br, solver.S_bz, solver.S_rz = b.T @ r, b.sum(axis=0)[:, None], r.sum(axis=0)[:, None]
        solver.S_rr, solver.S_bb = r.T @ r, float((b * b).sum())
        solver.n_obs, solver.S_zz = len(b), np.array([[float(len(b))]])
        solver.rho = 1.0 / max(len(b), 1)
        return solver

    def _nuisance_inverse(self) -> np.ndarray:
        """(Σ w z zᵀ)⁺: zero before any weight (pseudo-inverse: a drift regressor that has not varied yet); once per
        change of the sums (the screen, the fit and K all ask for it)."""
        if self._G is None:
            self._G = (np.linalg.pinv(self.S_zz) if self.S_zz.size and self.S_zz[0, 0] > 0.0
                       else np.zeros_like(self.S_zz))
        return self._G

    def _centred(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The sums with the nuisance terms projected out: (Σ w b̃ r̃ᵀ, Σ w r̃ r̃ᵀ, Σ w |b̃|²)."""
        G = self._nuisance_inverse()
        S_br = self.S_br - self.S_bz @ G @ self.S_rz.T
        S_rr = self.S_rr - self.S_rz @ G @ self.S_rz.T
        return S_br, S_rr, self.S_bb - float(np.trace(self.S_bz @ G @ self.S_bz.T))

    @property
    def K(self) -> np.ndarray:
        return davenport(self._centred()[0])

    def quaternion(self) -> np.ndarray:
        """Current estimate of C_b^n(0) as [w, x, y, z]; identity before two observations (one without
        an offset)."""
        if self.n_obs < min(len(self.S_zz), 1) + 1:
            return np.array([1.0, 0.0, 0.0, 0.0])
        return quaternion_from_K(self.K)

    def _fit(self, C: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float] | None:
        """(C_b^n(0), centred Σ w r rᵀ, residual variance per axis) of this fit's attitude (or of ``C``),
        None before the fit has residual degrees of freedom."""
        n, m = self.n_obs, len(self.S_zz)
        if 3 * n - 3 - 3 * m <= 0 or n < 4:
            return None
        S_br_c, S_rr_c, S_bb_c = self._centred()
        C = dcm_from_quat(quaternion_from_K(davenport(S_br_c))) if C is None else C   # C_b^n(0): b = C^T r + c
        rss = S_bb_c - 2.0 * float(np.trace(C @ S_br_c)) + float(np.trace(S_rr_c))
        return C, S_rr_c, max(rss, 0.0) / (3 * n - 3 - 3 * m)

    def covariance(self) -> np.ndarray | None:
        """Covariance (3, 3) rad² of the estimate's rotation error in the reference (n0) axes, from the
        fit itself: residual variance per axis (white residuals assumed) times the inverse information
        Σ w [r̃×]ᵀ[r̃×] of the centred references; None before the fit has residual degrees of freedom."""
        fit = self._fit()
        if fit is None:
            return None
        _, S_rr_c, variance = fit
        return variance * np.linalg.inv(np.trace(S_rr_c) * np.eye(3) - S_rr_c)

    def _consistent(self, b: np.ndarray, r: np.ndarray, w: float, z: np.ndarray) -> bool:
        """Whether the pair's residual against the fit so far is inside the gate, judged by the residual's predicted
        covariance: the pair's own noise, the nuisance estimate's and the fit's attitude error seen through the
        centred reference (so the screen holds from the first pairs, while the fit is still rough)."""
        C, S_rr_c, variance = self._fit()
        G = self._nuisance_inverse()
        c = (self.S_bz - C.T @ self.S_rz) @ G     # (3, m): the nuisance vectors
        e = b - C.T @ r - c @ z
        seen = C.T @ skew(r - self.S_rz @ G @ z)   # d e / d θ, θ the fit's rotation error in n0 axes
        information = np.trace(S_rr_c) * np.eye(3) - S_rr_c
        S = (1.0 / w + float(z @ G @ z)) * np.eye(3) + seen @ np.linalg.solve(information, seen.T)
        return float(e @ np.linalg.solve(S, e)) <= self.gate_chi2 * max(variance, 1.0)


class GroupedWahba:
    """One attitude from groups of pairs in different units (m/s, rad, …), each a weighted
    :class:`CentredWahba` with its own constant: the losses add, so the Davenport matrices do.

    ``prepare(b, r, mu, group)`` tags each pair with its group's index; ``fold`` sends it there.
    The covariance sums each group's information over its own residual variance (under the joint
    attitude). Same interface as the other solvers.
    """

    solver = "grouped"

    def __init__(self, groups: int) -> None:
        self.groups = [CentredWahba(weighted=True) for _ in range(groups)]
        self.rho = 1.0
        self.trace_P = float("nan")
        self.rejected = 0

    def __copy__(self) -> GroupedWahba:
        # the coarse stage's scratch copy folds into its groups: they must be its own (each copies cheaply, its
        # fold assigns new arrays)
        clone = object.__new__(GroupedWahba)
        clone.__dict__.update(self.__dict__)
        clone.groups = [copy.copy(g) for g in self.groups]
        return clone

    @property
    def n_obs(self) -> int:
        return sum(g.n_obs for g in self.groups)

    def prepare(self, b: np.ndarray, r: np.ndarray, mu: np.ndarray, group: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """(w b rᵀ (M, 3, 3), [b, r, w, 1, group] (M, 9)) of M pairs, for :meth:`fold`."""
        outer, pairs = self.groups[0].prepare(b, r, mu)
        return outer, np.column_stack((pairs, group))

    def fold(self, outer: np.ndarray, pairs: np.ndarray) -> None:
        """Each pair into its group, in order (same bits however grouped)."""
        for k in range(len(pairs)):
            self.groups[int(pairs[k, -1])].fold(outer[k:k + 1], pairs[k:k + 1, :-1])
        self.rho = 1.0 / max(self.n_obs, 1)

    @property
    def K(self) -> np.ndarray:
        return sum(g.K for g in self.groups)

    def quaternion(self) -> np.ndarray:
        """Current estimate of C_b^n(0) as [w, x, y, z]; identity before two observations."""
        if self.n_obs < 2:
            return np.array([1.0, 0.0, 0.0, 0.0])
        return quaternion_from_K(self.K)

    def covariance(self) -> np.ndarray | None:
        """Covariance (3, 3) rad² of the joint estimate's rotation error in the reference axes: the inverse of
        Σ information_g / residual variance_g over the groups that have residual degrees of freedom."""
        C = dcm_from_quat(self.quaternion())
        information = np.zeros((3, 3))
        for g in self.groups:
            fit = g._fit(C)
            if fit is not None:
                _, S_rr_c, variance = fit
                information += (np.trace(S_rr_c) * np.eye(3) - S_rr_c) / max(variance, 1e-30)
        if not information.any():
            return None
        return np.linalg.inv(information + 1e-30 * np.eye(3))


class WhitenedWahba(CentredWahba):
    """Generalised least squares for b = A r on a fixed base: α increments, whitened, in a weighted Wahba.

    Pairs are the increments Δb_k = α(t_k) − α(t_{k-1}) (b0 axes) and Δr_k = β(t_k) − β(t_{k-1})
    (n0 axes), m/s, so Δb_k = A Δr_k + n_k with the noise, per axis,

        n_k = g Δt_k θ_k + (v_k − v_{k-1}) + w_k,

    θ_k the gyro's angle random walk in C_b^{b0} (density ``arw_rad_rts``), w_k the accelerometer's
    white noise over the interval (variance VRW² Δt_k) and v_k a bounded velocity-like disturbance
    (independent, variance ``disturbance_velocity_mps``²; the same figure as OPREQ's μ). The noise is
    far from white: θ walks, and OPREQ must leave it out of μ (sensor_model.observation_variance).
    A Kalman filter of that noise, state [θ_k, v_k, v_{k-1}] per axis, turns it into its innovations
    e_k (white, variance S_k). Being linear, the same filter run on the Δb and on the Δr sequences
    gives pairs ẽb_k = A ẽr_k + e_k exactly; their weighted Wahba (weights 1/S_k) is the maximum-
    likelihood attitude. The gyro bias ramps θ like a heading error ramps the data, so the result
    keeps the bias limit (docs/algorithms/coarse.md, "Accuracy limits").

    Memory O(1): the last epoch and α, β; the two filters' states (3, 6); the filter covariance.
    ``prepare`` runs the filters (sequentially: same bits however the pairs are grouped into calls);
    ``fold`` adds the whitened pairs to the Wahba sums.
    """

    solver = "gls"

    def __init__(self, vrw_ms_rts: float, arw_rad_rts: float, gravity: float,
                 disturbance_velocity_mps: float = 1e-3) -> None:
        super().__init__(weighted=True, offset=False)
        self._white = vrw_ms_rts**2
        self._walk = arw_rad_rts**2
        self._disturbance = disturbance_velocity_mps**2
        self._gravity = gravity
        self._last = np.zeros(7)                 # [t, α (3), β (3)] of the last epoch: t = 0 at the start
        self._state = np.zeros((3, 6))           # rows θ, v_k, v_{k-1}; columns: the b and the r sequence
        # P as its six distinct entries (00, 01, 02, 11, 12, 22); at the start v_0 is unknown, θ_0 = 0
        self._P = (0.0, 0.0, 0.0, self._disturbance, 0.0, 0.0)

    def prepare(self, b: np.ndarray, r: np.ndarray, mu: np.ndarray | None, elapsed_s: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Whitened increment pairs of the cumulative b = α (M, 3) and r = β (M, 3) at ``elapsed_s`` (M,)
        seconds after the start, for :meth:`fold`. ``mu`` (OPREQ's model) is not used."""
        elapsed_s = np.asarray(elapsed_s, dtype=float)
        db, dr, S = np.empty_like(b), np.empty_like(r), np.empty(len(b))
        last, x = self._last, self._state
        p00, p01, p02, p11, p12, p22 = self._P
        for k in range(len(b)):
            now = np.concatenate(([elapsed_s[k]], b[k], r[k]))
            dt = now[0] - last[0]
            # predict: θ walks, v_k becomes v_{k-1}, a fresh v_k
            p00, p01, p02, p11, p12, p22 = p00 + self._walk * dt, 0.0, p01, self._disturbance, 0.0, p11
            x = np.array([x[0], np.zeros(6), x[1]])
            h = self._gravity * dt                                   # n_k = [h, 1, -1] · state + w_k
            PH = (h * p00 + p01 - p02, h * p01 + p11 - p12, h * p02 + p12 - p22)
            S[k] = h * PH[0] + PH[1] - PH[2] + self._white * dt
            innovation = now[1:] - last[1:] - (h * x[0] + x[1] - x[2])
            gain = np.array(PH) / S[k]
            x = x + gain[:, None] * innovation
            p00, p01, p02 = p00 - gain[0] * PH[0], p01 - gain[0] * PH[1], p02 - gain[0] * PH[2]
            p11, p12, p22 = p11 - gain[1] * PH[1], p12 - gain[1] * PH[2], p22 - gain[2] * PH[2]
            db[k], dr[k] = innovation[:3], innovation[3:]
            last = now
        self._last, self._state, self._P = last, x, (p00, p01, p02, p11, p12, p22)
        return super().prepare(db, dr, S)


GATE_MIN_PAIRS = 4
"""Pairs the fit needs before it screens new ones: its first residual degrees of freedom. The screen's covariance
carries the rough early fit's own error, so it need not wait for a settled fit (it waited for 20 pairs: 20 s of a
1-Hz receiver, whose glitch at 5 s then left the heading 26° off at 10 s)."""
GATE_REOPEN_PAIRS = 30
"""Rejections in a row after which the screen lets as many pairs through (3 s of 10-Hz pairs: longer than a
glitch)."""


def make_solver(name: str, rho: float = 0.01, grade: SensorGrade | None = None, gravity: float = 9.8,
                disturbance_velocity_mps: float = 1e-3) -> RecursiveK | CentredWahba:
    """The solver named in the configuration (``alignment.solver``); "gls" needs the sensor ``grade``, the
    site's gravity (m/s²) and the disturbance figure of its noise model."""
    if name == "gls":
        if grade is None:
            raise ValueError("the gls solver needs the sensor grade for its noise model")
        return WhitenedWahba(grade.acc_vrw_ms_rts, grade.gyro_arw_rad_rts, gravity, disturbance_velocity_mps)
    return CentredWahba() if name == "centred" else RecursiveK(name, rho)
