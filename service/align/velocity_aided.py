"""Inertial-frame alignment on a moving base aided by body-frame velocity (seed 003; docs/algorithms/odometer.md).

Exact identity: C_b^n(0) α(t) = β(t) with
α = ∫ C_b^{b0} f^b dt − C_b^{b0} V^b(t) + V^b(0) and β = ∫ C_n^{n0} (−g^n + ω_ie^n × V^n) dt
(signs as the fixed-site source: with V = 0 they are ∫ C f and −∫ C g). β needs V^n = C_b^n V^b,
hence an attitude, and C_{n(t)}^{n0} turns with the Earth rate *and* the transport rate of the
position the velocity carries. The multistage method: level 1 is the traditional V^b model
(β = −∫ C_n^{n0} g^n with the Earth rate only: the fixed-site closed form); each further level
recomputes β over the stored window with the previous level's attitude (dual-velocity model) and
solves again. Each level's error shrinks by about four. The first aiding sample V^b(0) is one
noisy constant in every α, so the solver must absorb constants common to all pairs
(``CentredWahba``, the default of the aided modes).

:class:`VelocityAidedSource` is the streaming observation source: it stores the first
``window_s`` seconds of observations (bounded: window / interval rows) and re-runs the levels on
them when asked (:meth:`VelocityAidedSource.relevel`); :func:`multistage` is the offline core.
"""
from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

import numpy as np

from .coarse import InertialCoarseAlignment
from .conventions import DEG, cross, dcm_from_quat, quat_from_dcm, quat_from_rotvec, rotvec_from_quat
from .earth import C_n_n0_fixed, Site, beta_fixed, earth_rate_n, normal_gravity, position_rate, transport_rate_n
from .sensor_model import ESTIMATOR_EFFICIENCY, SIGMA_UNKNOWN_DEG, bias_limit_rad
from .solvers import CentredWahba, make_solver
from .strapdown import prefix_quat_product

RESIDUAL_REJECT_FACTOR = 6.0
"""A pair whose residual exceeds this many times the median residual (robust σ ≈ median / 1.54 for
3-D Gaussian noise, so about 9σ) is an outlier: a slipping wheel, a DVL glitch."""
RESIDUAL_FLOOR_MPS = 0.05
"""Residuals below this are never rejected, however quiet the others (noise-free data)."""


@dataclass(frozen=True, slots=True)
class VelocityWindow:
    """Stored epochs: time since the start (N,) s, ∫C_b^{b0} f^b dt (N, 3) m/s, C_b^{b0} (N, 3, 3),
    aiding V^b (N, 3) m/s at the epochs, and V^b at the start (3,)."""

    elapsed_s: np.ndarray
    alpha_f: np.ndarray
    C_b_b0: np.ndarray
    V_b: np.ndarray
    V_b0: np.ndarray

    @property
    def V_b0_axes(self) -> np.ndarray:
        """C_b^{b0} V^b (N, 3): the aiding velocity in b0 axes."""
        return (self.C_b_b0 @ self.V_b[..., None])[..., 0]

    def observation_vectors(self) -> np.ndarray:
        """α (N, 3): ∫ C f − C_b^{b0} V^b + V^b(0)."""
        return self.alpha_f - self.V_b0_axes + self.V_b0


@dataclass(frozen=True, slots=True)
class NavTrack:
    """Where the window's epochs put the vehicle under one attitude estimate.

    C_n_n0 (N, 3, 3), position (N, 3) lat rad / lon rad / h m, V^n (N, 3) m/s, β (N, 3) m/s.
    """

    C_n_n0: np.ndarray
    position: np.ndarray
    V_n: np.ndarray
    beta: np.ndarray


def fixed_track(start: Site, elapsed_s: np.ndarray) -> NavTrack:
    """The traditional model's track: no motion, Earth rate only (level 1)."""
    n = len(elapsed_s)
    return NavTrack(C_n_n0_fixed(start.lat, elapsed_s), np.tile([start.lat, start.lon, start.height_m], (n, 1)),
                    np.zeros((n, 3)), beta_fixed(start.lat, start.gravity, elapsed_s))


def _cumulative_trapezoid(elapsed_s: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """∫_0^t rate, holding the first value over the first interval (it starts at the alignment start)."""
    steps = 0.5 * np.diff(elapsed_s)[:, None] * (rate[1:] + rate[:-1])
    return elapsed_s[0] * rate[0] + np.concatenate((np.zeros((1, rate.shape[1])), np.cumsum(steps, axis=0)))


def dual_velocity_track(window: VelocityWindow, start: Site, C_b0_n0: np.ndarray, previous: NavTrack) -> NavTrack:
    """β and the track of the dual-velocity model under attitude ``C_b0_n0``, vectorised.

    V^n = C_{n0}^{n} C_b0^n0 C_b^{b0} V^b uses the previous track's C_n^{n0}; position and
    C_{n}^{n0} (Earth plus transport rate) integrate by the trapezoid rule between epochs with the
    previous track's latitude and height. One level lags the next by these small terms only, and
    the levels converge to the exact track together with the attitude.
    """
    t = window.elapsed_s
    V_n = np.einsum("nji,nj->ni", previous.C_n_n0, window.V_b0_axes @ C_b0_n0.T)
    lat, h = previous.position[:, 0], previous.position[:, 2]
    position = np.array([start.lat, start.lon, start.height_m]) + _cumulative_trapezoid(
        t, position_rate(V_n, lat, h))
    omega_ie_n = earth_rate_n(lat)
    rate = omega_ie_n + transport_rate_n(V_n, lat, h)
    dt = np.diff(t, prepend=0.0)
    # C_{n(t_k)}^{n0}: product of the step rotations, each with the mean rate of its ends
    mean_rate = np.concatenate((rate[:1], 0.5 * (rate[1:] + rate[:-1])))
    q = prefix_quat_product(quat_from_rotvec(mean_rate * dt[:, None]))
    C_n_n0 = dcm_from_quat(q)
    g_n = np.zeros_like(V_n)
    g_n[:, 2] = -normal_gravity(lat, h)
    integrand = np.einsum("nij,nj->ni", C_n_n0, -g_n + cross(omega_ie_n, V_n))
    return NavTrack(C_n_n0, position, V_n, _cumulative_trapezoid(t, integrand))


@dataclass(frozen=True, slots=True)
class MultistageResult:
    """Each level's C_b0^n0, the last level's track, which pairs it kept, the noise covariance
    (3, 3) rad² of its attitude error in n0 axes (from the residuals of the kept pairs), and the
    nuisance parameters it fitted with their 1-sigma (:class:`Nuisance`: accelerometer bias in body
    axes, odometer scale factor and lever arm; only those asked for)."""

    levels: list[np.ndarray]
    track: NavTrack
    kept: np.ndarray
    covariance: np.ndarray
    nuisance: dict[str, np.ndarray]
    nuisance_sigma: dict[str, np.ndarray]

    @property
    def acc_bias_ms2(self) -> np.ndarray:
        return self.nuisance.get("acc_bias", np.zeros(3))


def _solve(alpha: np.ndarray, beta: np.ndarray, keep: np.ndarray, solver: str) -> np.ndarray:
    if solver == "centred":
        s = CentredWahba.from_pairs(alpha[keep], beta[keep])
    else:
        s = make_solver(solver)
        s.fold(*s.prepare(alpha[keep], beta[keep], np.ones(int(keep.sum()))))
    return dcm_from_quat(s.quaternion())


def centred_residuals(alpha: np.ndarray, beta: np.ndarray, C_b0_n0: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """|α_k − A β_k − c| (N,) with A = C_n0^b0 and the constant c fitted over the kept pairs."""
    e = alpha - beta @ C_b0_n0     # rows: (C_n0^b0 β_k)ᵀ = β_kᵀ C_b0^n0
    return np.linalg.norm(e - e[keep].mean(axis=0), axis=1)


def bias_integral(window: VelocityWindow) -> np.ndarray:
    """J_k = ∫_0^{t_k} C_b^{b0} dt (N, 3, 3): how a constant accelerometer bias ∇ (body axes) enters α_k."""
    C = window.C_b_b0
    t = window.elapsed_s
    first = 0.5 * t[0] * (np.eye(3) + C[0])
    steps = 0.5 * np.diff(t)[:, None, None] * (C[1:] + C[:-1])
    return first + np.concatenate((np.zeros((1, 3, 3)), np.cumsum(steps, axis=0)))


@dataclass(frozen=True, slots=True)
class Nuisance:
    """Parameters fitted alongside the attitude, linear in α: α_k = A β_k + c + X_k x + noise.

    X (N, 3, m) per epoch; x has the prior N(mean, sigma²) per component (sigma 0: held at its mean).
    ``names`` (m,) say which is which: acc_bias (∇, body axes, m/s²), odo_scale, odo_lever (body, m).
    """

    X: np.ndarray
    mean: np.ndarray
    sigma: np.ndarray
    names: tuple[str, ...]

    def split(self, x: np.ndarray) -> dict[str, np.ndarray]:
        out: dict[str, list[float]] = {}
        for name, value in zip(self.names, x, strict=True):
            out.setdefault(name, []).append(float(value))
        return {k: np.array(v) for k, v in out.items()}


def body_rates(window: VelocityWindow) -> np.ndarray:
    """ω_ib^b (N, 3) rad/s at the epochs, by central differences of the stored C_b^{b0}."""
    C, t = window.C_b_b0, window.elapsed_s
    if len(t) < 2:
        return np.zeros((len(t), 3))
    before, after = np.r_[0, np.arange(len(t) - 1)], np.r_[np.arange(1, len(t)), len(t) - 1]
    step = rotvec_from_quat(quat_from_dcm(np.swapaxes(C[before], 1, 2) @ C[after]))
    return step / (t[after] - t[before])[:, None]


def nuisance_model(window: VelocityWindow, acc_bias_sigma_ms2: float = 0.0, odo_scale_sigma: float = 0.0,
                   odo_lever_m: np.ndarray | None = None, odo_lever_sigma_m: float = 0.0) -> Nuisance | None:
    """The nuisance parameters of a body-velocity window: accelerometer bias (∫C_b^{b0} dt ∇), odometer
    scale factor (the reading (1 + k) V^b puts −k C_b^{b0} V^b into α) and lever arm (−C_b^{b0} ω × l)."""
    blocks, means, sigmas, names = [], [], [], []
    if acc_bias_sigma_ms2 > 0.0:
        blocks.append(bias_integral(window))
        means += [0.0] * 3
        sigmas += [acc_bias_sigma_ms2] * 3
        names += ["acc_bias"] * 3
    if odo_scale_sigma > 0.0:
        blocks.append(-window.V_b0_axes[:, :, None])
        means.append(0.0)
        sigmas.append(odo_scale_sigma)
        names.append("odo_scale")
    lever = np.zeros(3) if odo_lever_m is None else np.asarray(odo_lever_m, dtype=float)
    if odo_lever_sigma_m > 0.0 or lever.any():
        blocks.append(-window.C_b_b0 @ skew_rows(body_rates(window)))
        means += list(lever)
        sigmas += [odo_lever_sigma_m] * 3
        names += ["odo_lever"] * 3
    if not blocks:
        return None
    return Nuisance(np.concatenate(blocks, axis=2), np.array(means), np.array(sigmas), tuple(names))


def joint_fit(alpha: np.ndarray, beta: np.ndarray, C_b0_n0: np.ndarray, keep: np.ndarray,
              nuisance: Nuisance | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linearised least squares about A = C_n0^b0 of α_k − A β_k = A [β_k×] δθ + c + X_k x + noise.

    δθ (n0 axes) and c are free, x has its prior (turns make the bias and lever arm observable,
    speed changes the scale factor; what the drive leaves unobservable stays at the prior). Returns
    (x (m,), its covariance (m, m), covariance of δθ (3, 3) rad²), the noise variance per axis from
    the residuals.
    """
    r = beta[keep]
    e = alpha[keep] - r @ C_b0_n0
    G = C_b0_n0.T @ skew_rows(r)                                    # A [β_k×]  (n, 3, 3)
    n = len(r)
    m = 0 if nuisance is None else len(nuisance.mean)
    D = G if nuisance is None else np.concatenate((G, nuisance.X[keep]), axis=2)
    D = D - D.mean(axis=0)                                          # centring removes c
    e = e - e.mean(axis=0)
    D_rows = D.reshape(-1, D.shape[2])                              # (3n, 3 + m): one row per axis and pair
    M = D_rows.T @ D_rows
    v = D_rows.T @ e.reshape(-1)
    x_plain = np.linalg.lstsq(M, v, rcond=None)[0]
    sigma2 = max(float(((e.reshape(-1) - D_rows @ x_plain) ** 2).sum()) / max(3 * n - 6 - m, 1), 1e-12)
    if nuisance is not None:
        # prior N(mean, σ²) as pseudo-observations; σ = 0 holds the parameter at its mean
        weight = np.where(nuisance.sigma > 0.0, sigma2 / np.maximum(nuisance.sigma, 1e-300) ** 2, 1e12 * np.trace(M))
        M = M + np.diag(np.r_[np.zeros(3), weight])
        v = v + np.r_[np.zeros(3), weight * nuisance.mean]
    M = M + 1e-12 * np.trace(M) * np.eye(len(M))
    x = np.linalg.solve(M, v)
    covariance = sigma2 * np.linalg.inv(M)
    return x[3:], covariance[3:, 3:], covariance[:3, :3]


def skew_rows(v: np.ndarray) -> np.ndarray:
    """[v_k×] (N, 3, 3) of rows v (N, 3)."""
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return S


def multistage(window: VelocityWindow, start: Site, levels: int = 10, solver: str = "centred",
               first: np.ndarray | None = None, acc_bias_sigma_ms2: float = 0.0,
               nuisance: Nuisance | None = None) -> MultistageResult:
    """Levels 1..``levels`` over the window at once (see :func:`multistage_levels`); ``nuisance``
    defaults to the accelerometer bias alone with prior ``acc_bias_sigma_ms2``."""
    if nuisance is None:
        nuisance = nuisance_model(window, acc_bias_sigma_ms2)
    steps = multistage_levels(window, start, levels, solver, first, nuisance)
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


def multistage_levels(window: VelocityWindow, start: Site, levels: int = 10, solver: str = "centred",
                      first: np.ndarray | None = None, nuisance: Nuisance | None = None
                      ) -> Generator[None, None, MultistageResult]:
    """Levels 1..``levels`` over the window, one level per ``next()`` (the live daemon slices them);
    the generator's return value is the :class:`MultistageResult`.

    Level 1 is traditional, or ``first`` given: a level-1 estimate already at hand. From level 2 on,
    pairs whose residual is an outlier are left out. Each level also fits the ``nuisance`` parameters
    (:func:`joint_fit`): on a turning vehicle a body-fixed accelerometer bias integrates to
    ∫ C_b^{b0} ∇ dt, no longer a tilt, and would pull the heading by degrees; so would an odometer
    scale factor of half a percent (tens of degrees) or a lever arm of a metre.
    """
    alpha = window.observation_vectors()
    track = fixed_track(start, window.elapsed_s)
    keep = np.ones(len(alpha), dtype=bool)
    x = np.zeros(0) if nuisance is None else nuisance.mean.copy()
    x_covariance = np.zeros((len(x), len(x)))

    def corrected() -> np.ndarray:
        return alpha if nuisance is None else alpha - nuisance.X @ x

    estimates = [_solve(corrected(), track.beta, keep, solver) if first is None else first]
    covariance = np.full((3, 3), np.nan)
    for _ in range(levels - 1):
        track = dual_velocity_track(window, start, estimates[-1], track)
        alpha_c = corrected()
        estimate = _solve(alpha_c, track.beta, keep, solver)
        residual = centred_residuals(alpha_c, track.beta, estimate, keep)
        limit = max(RESIDUAL_REJECT_FACTOR * float(np.median(residual[keep])), RESIDUAL_FLOOR_MPS)
        outliers = keep & (residual > limit)
        if outliers.any():
            keep = keep & ~outliers
            estimate = _solve(alpha_c, track.beta, keep, solver)
        x, x_covariance, covariance = joint_fit(alpha, track.beta, estimate, keep, nuisance)
        estimates.append(estimate)
        yield
    if levels == 1:
        covariance = joint_fit(alpha, track.beta, estimates[0], keep, None)[2]
    fitted = {} if nuisance is None else nuisance.split(x)
    fitted_sigma = {} if nuisance is None else nuisance.split(np.sqrt(np.diag(x_covariance)))
    return MultistageResult(estimates, track, keep, covariance, fitted, fitted_sigma)


def multistage_alignment(window: VelocityWindow, start: Site, levels: int = 10,
                         solver: str = "centred") -> list[np.ndarray]:
    """C_{b0}^{n0} (3, 3) after each level: level 1 traditional, then dual-velocity re-runs."""
    return multistage(window, start, levels, solver).levels


class VelocityAidedSource:
    """Observation source of a base moving with a measured body velocity V^b (odometer, DVL).

    Pairs: b = α (above, with V^b of the observation epoch), r = β of the traditional model (the
    running solver's level 1). The first ``window_s`` seconds of observations are stored; after
    :meth:`relevel` the multistage estimate and its track replace level 1, and C_{n}^{n0} follows
    the position its velocity carries (Earth plus transport rate), also beyond the window.

    site : position at the alignment start. window_s, obs_interval_s : size the store.
    levels : multistage levels. solver : the solver of each level.
    priors : keyword arguments of :func:`nuisance_model` (accelerometer bias, odometer scale factor and
        lever arm priors) for the parameters each level fits alongside the attitude.
    """

    aid_width = 3

    def __init__(self, site: Site, window_s: float, obs_interval_s: float, levels: int = 10,
                 solver: str = "centred", priors: dict | None = None) -> None:
        self.site = site
        self.priors = priors or {}
        self.levels = levels
        self.solver = solver
        self._store = np.empty((int(np.ceil(window_s / obs_interval_s + 1e-9)), 16))
        self._n = 0
        self.V_b0: np.ndarray | None = None
        self.result: MultistageResult | None = None
        self._relevel: tuple[VelocityWindow, Generator[None, None, MultistageResult]] | None = None
        self.relevel_window_full = False
        self._head: tuple[float, np.ndarray, np.ndarray] | None = None   # (elapsed, C_n_n0, position) latest

    def window_full(self, elapsed_s: float) -> bool:
        """Whether the store holds the whole window by ``elapsed_s`` (rows may be stored ahead of it)."""
        return self._n == len(self._store) and self._store[-1, 0] <= elapsed_s + 1e-9

    @property
    def C_b0_n0(self) -> np.ndarray | None:
        """The multistage estimate of C_b0^n0, None before the first :meth:`relevel`."""
        return None if self.result is None else self.result.levels[-1]

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        if aid is None:
            raise ValueError("a velocity-aided source needs V^b at every observation")
        V_b, C_b_b0 = aid, dcm_from_quat(q_b_b0)
        if len(elapsed_s) and self.V_b0 is None:
            self.V_b0 = V_b[0].copy()
        fits = min(len(elapsed_s), len(self._store) - self._n)
        if fits:
            rows = self._store[self._n:self._n + fits]
            rows[:, 0], rows[:, 1:4], rows[:, 4:13], rows[:, 13:] = (
                elapsed_s[:fits], alpha_b0[:fits], C_b_b0[:fits].reshape(-1, 9), V_b[:fits])
            self._n += fits
        b = alpha_b0 - (C_b_b0 @ V_b[..., None])[..., 0] + (self.V_b0 if self.V_b0 is not None else 0.0)
        return b, beta_fixed(self.site.lat, self.site.gravity, elapsed_s)

    def window(self, upto_elapsed_s: float = np.inf) -> VelocityWindow:
        """The stored epochs up to ``upto_elapsed_s`` (a chunk of samples may store rows ahead of the step)."""
        rows = self._store[:int(np.searchsorted(self._store[:self._n, 0], upto_elapsed_s + 1e-9))]
        return VelocityWindow(rows[:, 0], rows[:, 1:4], rows[:, 4:13].reshape(-1, 3, 3), rows[:, 13:],
                              self.V_b0 if self.V_b0 is not None else np.zeros(3))

    def start_relevel(self, upto_elapsed_s: float, first: np.ndarray | None = None) -> bool:
        """Begin re-running the levels over the epochs stored up to ``upto_elapsed_s`` (``first``: a level-1
        estimate to start from instead of the traditional model); False if too few epochs yet."""
        window = self.window(upto_elapsed_s)
        if len(window.elapsed_s) < 10:
            return False
        self._relevel = (window, multistage_levels(window, self.site, self.levels, self.solver, first,
                                                   nuisance_model(window, **self.priors)))
        self.relevel_window_full = len(window.elapsed_s) == len(self._store)
        return True

    @property
    def relevelling(self) -> bool:
        return self._relevel is not None

    def step_relevel(self, levels: int | None = None) -> bool:
        """Run ``levels`` more levels of the re-run in progress (None: all); True once it is done and its
        estimate replaced the previous one."""
        window, steps = self._relevel
        for _ in range(levels if levels is not None else self.levels + 1):
            try:
                next(steps)
            except StopIteration as done:
                self.result, self._relevel = done.value, None
                track = self.result.track
                self._head = (float(window.elapsed_s[-1]), track.C_n_n0[-1], track.position[-1])
                return True
        return False

    def advance(self, elapsed_s: float, C_b_b0: np.ndarray, V_b: np.ndarray) -> None:
        """Carry position and C_n^{n0} on to ``elapsed_s`` with the latest estimate (one control step)."""
        t, C_n_n0, position = self._head
        V_n = C_n_n0.T @ self.C_b0_n0 @ C_b_b0 @ V_b
        lat, h = position[0], position[2]
        rate = earth_rate_n(lat) + transport_rate_n(V_n, lat, h)
        dt = elapsed_s - t
        self._head = (elapsed_s, C_n_n0 @ dcm_from_quat(quat_from_rotvec(rate * dt)),
                      position + dt * position_rate(V_n, lat, h))

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        if self._head is None:
            return C_n_n0_fixed(self.site.lat, elapsed_s)
        t, C_n_n0, position = self._head
        rate = earth_rate_n(position[0])   # the transport rate over a fraction of a step is below 1e-6 rad
        return C_n_n0 @ dcm_from_quat(quat_from_rotvec(rate * (elapsed_s - t)))

    @property
    def position(self) -> np.ndarray:
        """(lat rad, lon rad, h m) at the latest observation (the start before any relevel)."""
        return np.array([self.site.lat, self.site.lon, self.site.height_m]) if self._head is None else self._head[2]

    def sigma_rad(self) -> tuple[float, float] | None:
        """1-sigma (heading, level) noise errors of the multistage estimate, rad, or None."""
        if self.result is None:
            return None
        P = self.result.covariance
        return float(np.sqrt(P[2, 2])), float(np.sqrt(0.5 * (P[0, 0] + P[1, 1])))



class MultistageCoarseAlignment(InertialCoarseAlignment):
    """The coarse stage of the velocity-aided mode: the core's streaming solver (level 1) until the
    first :meth:`relevel`, then the source's multistage estimate and its residual-based σ."""

    source: VelocityAidedSource

    def start_relevel(self, elapsed_s: float) -> bool:
        """Begin a re-run of the levels on the window up to ``elapsed_s``, the first level from the previous
        run's estimate: over successive runs the levels converge to the exact (dual-velocity) solution,
        however short the early windows were."""
        return self.source.start_relevel(elapsed_s, self.source.C_b0_n0 if self.source.levels > 1 else None)

    @property
    def q_b_n0(self) -> np.ndarray:
        C_b0_n0 = self.source.C_b0_n0
        return self.solver.quaternion() if C_b0_n0 is None else quat_from_dcm(C_b0_n0)

    def sigma(self, elapsed_s: float) -> tuple[float, float]:
        """1-sigma (heading, level) in degrees: the fit's noise part (times the estimator efficiency, the
        same calibration as the fixed-site σ: seed-003 Monte Carlo at 80 m/s, heading STD 0.23° over
        seeds against a fit σ of 0.17°, a variance ratio of 1.85), the bias limit, and the drift of
        the integrated body attitude since the start (ε t)."""
        noise = self.source.sigma_rad()
        if noise is None:
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        noise = tuple(np.sqrt(ESTIMATOR_EFFICIENCY) * n for n in noise)
        bias_heading, bias_level = bias_limit_rad(self.grade, self.source.site.lat, self.source.site.gravity)
        drift = self.grade.gyro_bias_rad_s * max(elapsed_s, 0.0)
        heading, level = (float(np.sqrt(n**2 + b**2 + drift**2)) / DEG
                          for n, b in zip(noise, (bias_heading, bias_level), strict=True))
        return min(heading, SIGMA_UNKNOWN_DEG), min(level, SIGMA_UNKNOWN_DEG)
