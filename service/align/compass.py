"""Compass (gyrocompass-loop) fine alignment on a base fixed in position (seed 001; docs/algorithms/compass.md).

The platform frame p is the computed navigation frame. It is kept as C_{b0}^{p}: b0 is the
inertially frozen body frame of the coarse stage, so the body attitude C_{b(t)}^{b0} and the
specific-force integral α(t) of the shared strapdown integrator are all the loops need, and the
current attitude is C_b^p(t) = C_{b0}^{p}(t) · C_{b(t)}^{b0}. Every control step of length Δ
(a whole number of IMU samples) takes the b0-frame velocity increment Δα over the step:

    V^p  += C_{b0}^{p}(mid) Δα + g^n Δ − 2 ω_ie^n × V^p Δ − K1 ⊙ V^p Δ     (horizontal only)
    C_{b0}^{p} ← exp(−[ω_p Δ ×]) C_{b0}^{p},   ω_p = s ω_ie^n + ω_c       (s = ±1, see below)

with the commanded rate ω_c held over the step (computed from the state at its start):

    level loops (third order):  ω_cE = −(1 + K2) V_N / R − I_N,   İ_N = K3 V_N
                                ω_cN = +(1 + K2) V_E / R + I_E,   İ_E = K3 V_E
    azimuth loop (fourth order, north channel, replaces its level loop):
                                ω_cE = −(1 + K2) V_N / R,   ω_cU = y,
                                ẏ = −K3 y + K4 / (s Ω cos L) · V_N

Error model (φ as in conventions.py, C_b^p = (I − [φ×]) C_b^n): δV̇_E = −g φ_N, δV̇_N = g φ_E,
φ̇ = −ω_ie^n × φ + ω_c − ε^n. Its characteristic polynomials are the ones of docs/algorithms/compass.md, so the
gains come from pole placement: level s³ + K1 s² + ω_s²(1+K2) s + g K3 = (s+σ)(s²+2σs+2σ²)
(ξ = 0.707, ω_d = σ), azimuth s(s+K3)(s²+K1 s+ω_s²(1+K2)) + g K4 = (s²+2σs+2σ²)². We keep the
integrator gain K3 with the factor σ (seed 001 prints it without).

Reverse-time passes (stored data) run the same step on the reversed world: samples in reverse
order, Earth rate negated (s = −1), velocity negated. :meth:`CompassLoops.reverse` performs the
switch so that it causes no transient: the damping tilt 2 K1 V / g that the loops hold on purpose
is re-applied with the new velocity sign, the level integrators (which balance the Earth-rate and
gyro-bias coupling) change sign with them, and the azimuth command keeps its sign (it corrects
the same physical heading error in both directions).

Honest uncertainty: the linear error model with white accelerometer and gyro noise propagates
a covariance P over every step (transients, gain changes and passes included); the reported σ
adds the bias limit and the azimuth offset −2 ε_U / σ_A.
"""
from __future__ import annotations

import itertools
import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ._attitude import fine_record_angles
from ._compass import (
    azimuth_gains,
    compass_step,
    compass_steps,
    level_gains,
    platform_attitude,
    process_noise,
    schedule_sigma,
    transition,
)
from .conventions import EYE3, skew
from .earth import OMEGA_IE, Site, radii
from .sensor_model import ESTIMATOR_EFFICIENCY, SIGMA_UNKNOWN_DEG, AttitudeSigma, SensorGrade, bias_limit_rad

F_CACHE_SIZE = 256
"""Transition matrices kept (each an 8×8 matrix exponential of one set of gains, sign and step length)."""

# error-state indices of the covariance model
VE, VN, PE, PN, PU, IE, IN, YU = range(8)
_NO_AZIMUTH = (0.0, 0.0, 0.0, 0.0)   # the azimuth gains the compiled step is given while its loop is off (unread)


@dataclass(frozen=True, slots=True)
class GainSchedule:
    """Loop bandwidths σ (rad/s) against loop time since the fine stage started (s).

    Between knots σ is interpolated geometrically, so the gains change smoothly and the commanded
    rate never steps. An azimuth σ of 0 means the azimuth loop is off (levelling first); it
    switches on at the first knot with a positive azimuth σ, and stays on.
    """

    time_s: tuple[float, ...]
    level_sigma: tuple[float, ...]
    azimuth_sigma: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.time_s)
        if n == 0 or len(self.level_sigma) != n or len(self.azimuth_sigma) != n:
            raise ValueError("schedule: time_s, level_sigma and azimuth_sigma need the same, non-zero length")
        if any(b <= a for a, b in zip(self.time_s, self.time_s[1:], strict=False)) or self.time_s[0] != 0.0:
            raise ValueError("schedule: time_s must start at 0 and increase")
        if any(s <= 0.0 for s in self.level_sigma) or any(s < 0.0 for s in self.azimuth_sigma):
            raise ValueError("schedule: level_sigma must be > 0 and azimuth_sigma ≥ 0")
        on = [s > 0.0 for s in self.azimuth_sigma]
        if any(a and not b for a, b in itertools.pairwise(on)) or not on[-1]:
            raise ValueError("schedule: once positive, azimuth_sigma must stay positive, and end positive")

    @property
    def final_time_s(self) -> float:
        return self.time_s[-1]

    def sigmas(self, t_s: float) -> tuple[float, float]:
        """(level σ, azimuth σ) at loop time ``t_s``; azimuth σ is 0 before its loop starts (compiled: the rule the
        block loop applies)."""
        return self.sigma_of(self.level_sigma, t_s), self.sigma_of(self.azimuth_sigma, t_s)

    def sigma_of(self, values: tuple[float, ...], t_s: float) -> float:
        """``values`` (one per knot) at loop time ``t_s``, interpolated geometrically."""
        return schedule_sigma(np.asarray(self.time_s, dtype=float), np.asarray(values, dtype=float), t_s)


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """exp([φ×]) (3, 3) by Rodrigues' formula, exact for any angle."""
    x, y, z = rotvec
    angle = float(np.sqrt(x * x + y * y + z * z))
    S = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    if angle < 1e-8:
        return EYE3 + S + 0.5 * S @ S
    return EYE3 + np.sin(angle) / angle * S + (1.0 - np.cos(angle)) / angle**2 * S @ S


@dataclass(slots=True)
class CompassState:
    """Everything one run of the loops carries; :meth:`copy` clones it for the stored-data passes.

    C_b0_p : C_{b0}^{p} (3, 3). V : platform velocity (E, N), m/s. I_E, I_N : level integrator
    rates (rad/s). y : azimuth command (rad/s). t_loop_s : loop time on the gain schedule (s).
    azimuth_on : the north channel runs the azimuth loop. earth_sign : +1 forward, −1 reverse time.
    P : (8, 8) error covariance (δV_E, δV_N, φ_E, φ_N, φ_U, I_E, I_N, y).
    """

    C_b0_p: np.ndarray
    V: np.ndarray = field(default_factory=lambda: np.zeros(2))
    I_E: float = 0.0
    I_N: float = 0.0
    y: float = 0.0
    t_loop_s: float = 0.0
    azimuth_on: bool = False
    earth_sign: float = 1.0
    P: np.ndarray = field(default_factory=lambda: np.zeros((8, 8)))

    def copy(self) -> CompassState:
        return CompassState(self.C_b0_p.copy(), self.V.copy(), self.I_E, self.I_N, self.y, self.t_loop_s,
                            self.azimuth_on, self.earth_sign, self.P.copy())


class CompassLoops:
    """The loop mechanics of one site, grade and gain schedule (stateless; states are passed in)."""

    def __init__(self, site: Site, grade: SensorGrade, schedule: GainSchedule) -> None:
        self.site = site
        self.grade = grade
        self.bias_grade = grade   # the biases σ reports: the datasheet's, or the larger the data show at any time
        self.schedule = schedule
        self.gravity = site.gravity
        R_M, R_N = radii(site.lat)
        self.radius_m = float(np.sqrt(R_M * R_N)) + site.height_m
        self.omega_cos = OMEGA_IE * np.cos(site.lat)
        self.omega_sin = OMEGA_IE * np.sin(site.lat)
        self.omega_ie_n = site.omega_ie_n
        self._F_cache: OrderedDict[tuple, np.ndarray] = OrderedDict()   # least recently used first
        self._F_last: tuple[tuple, np.ndarray | None] = ((), None)   # the newest key and its matrix
        self._gains_last: tuple[float, tuple] = (np.nan, ((), None))
        # past the schedule's end the gains are its final ones: one tuple, so the cache keys compare by identity
        self._gains_final = self._gains_from(*schedule.sigmas(schedule.final_time_s))
        self._Q_cache: dict[tuple, np.ndarray] = {}
        self._Q_last: tuple[float, SensorGrade | None, np.ndarray | None] = (np.nan, None, None)

    def start(self, C_b_n: np.ndarray, C_b_b0: np.ndarray, tilt_sigma_rad: float,
              heading_sigma_rad: float, t_loop_s: float = 0.0) -> CompassState:
        """A fresh loop state from the attitude C_b^n (its 1-sigma noise errors seed P), at loop time ``t_loop_s``."""
        P = np.zeros((8, 8))
        P[PE, PE] = P[PN, PN] = tilt_sigma_rad**2
        P[PU, PU] = heading_sigma_rad**2
        return CompassState(C_b_n @ C_b_b0.T, t_loop_s=t_loop_s, P=P)

    def _gains(self, state: CompassState) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        return self.gains_at(state.t_loop_s)

    def gains_at(self, t_loop_s: float) -> tuple[tuple[float, float, float], tuple[float, float, float, float] | None]:
        """(level K1..K3, azimuth K1..K4 or None while it is off) at loop time ``t_loop_s``."""
        if self._gains_last[0] == t_loop_s:   # a step asks twice, and the stored passes hold the loop time
            return self._gains_last[1]
        gains = (self._gains_final if t_loop_s >= self.schedule.final_time_s
                 else self._gains_from(*self.schedule.sigmas(t_loop_s)))
        self._gains_last = (t_loop_s, gains)
        return gains

    def _gains_from(self, level_sigma: float, azimuth_sigma: float) -> tuple[tuple, tuple | None]:
        level = level_gains(level_sigma, self.gravity, self.radius_m)
        return level, azimuth_gains(azimuth_sigma, self.gravity, self.radius_m) if azimuth_sigma > 0.0 else None

    def record_angles(self, state: CompassState, lat: float, elapsed_s: float, q_b_n0: np.ndarray, q_b_b0: np.ndarray,
                      coarse_sigma_deg: tuple[float, float], fine_sigma_deg: tuple[float, float],
                      since_step_s: float) -> tuple:
        """A fixed-base record's attitude beside the coarse stage's (q_b_n0 and its (heading, level) σ, ``elapsed_s``
        into the alignment at latitude ``lat``): :func:`~service.align._attitude.fine_record_angles` with this state
        ``since_step_s`` after its last step."""
        return fine_record_angles(lat, elapsed_s, q_b_n0, np.ascontiguousarray(q_b_b0, dtype=float), *coarse_sigma_deg,
                                  *fine_sigma_deg, *self._platform(state), since_step_s)

    def attitude(self, state: CompassState, C_b_b0: np.ndarray, since_step_s: float) -> np.ndarray:
        """C_b^n (3, 3) of the body attitude C_{b}^{b0} (3, 3), ``since_step_s`` after the state's last step: the
        platform turned on at ω_p = s ω_ie^n + ω_c, the rate the state commands (the module docstring), compiled
        (_compass.pyx)."""
        return platform_attitude(*self._platform(state), since_step_s, np.ascontiguousarray(C_b_b0, dtype=float))

    def _platform(self, state: CompassState) -> tuple:
        """What the compiled platform turn takes of a state and its gains: C_{b0}^{p}, V, I_E, I_N, y, whether the
        azimuth loop runs, K2 of the level and the azimuth loops, the Earth-rate sign, ω_ie^n and the radius."""
        level, azimuth = self._gains(state)
        on = state.azimuth_on and azimuth is not None
        return (state.C_b0_p, state.V, state.I_E, state.I_N, state.y, on, level[1], azimuth[1] if on else 0.0,
                state.earth_sign, self.omega_ie_n, self.radius_m)

    def step(self, state: CompassState, dalpha_b0: np.ndarray, dt_s: float, advance_schedule: bool = True) -> None:
        """Advance ``state`` by one control step with the b0-frame velocity increment Δα (m/s).

        ``advance_schedule`` False keeps the loop time (and so the gains) where it is: the
        stored-data passes run at the bandwidth the loops had when the buffer filled.
        """
        level, azimuth = self._azimuth_switch(state)
        F = self._transition(level, azimuth, state.earth_sign, dt_s)
        state.I_E, state.I_N, state.y = compass_step(
            state.C_b0_p, state.V, state.I_E, state.I_N, state.y, dalpha_b0, dt_s, *level, state.azimuth_on,
            *(azimuth or _NO_AZIMUTH), state.earth_sign, self.omega_ie_n, self.omega_cos, self.omega_sin,
            self.radius_m, F, self._process_noise(dt_s), state.P)
        if advance_schedule:
            state.t_loop_s += dt_s

    def steps_held(self, state: CompassState, dalpha_b0: np.ndarray, dt_s: np.ndarray) -> None:
        """:meth:`step` over N control steps (Δα (N, 3) m/s, Δ (N,) s) with the loop time held (the stored-data
        passes), in one compiled call: the gains stay, so each step takes the transition of its length."""
        level, azimuth = self._azimuth_switch(state)
        lengths = np.array(sorted(set(dt_s.tolist())))   # np.unique's, without its first call's import of numpy.ma
        which = np.searchsorted(lengths, dt_s)
        F = np.stack([self._transition(level, azimuth, state.earth_sign, float(d)) for d in lengths])
        Q = np.stack([self._process_noise(float(d)) for d in lengths])
        state.I_E, state.I_N, state.y = compass_steps(
            state.C_b0_p, state.V, state.I_E, state.I_N, state.y, np.ascontiguousarray(dalpha_b0),
            np.ascontiguousarray(dt_s), *level, state.azimuth_on, *(azimuth or _NO_AZIMUTH), state.earth_sign,
            self.omega_ie_n, self.omega_cos, self.omega_sin, self.radius_m, F, Q, which.astype(np.intp).reshape(-1),
            state.P)

    def _azimuth_switch(self, state: CompassState) -> tuple[tuple, tuple | None]:
        """The level gains and the azimuth gains the step runs with (None while the azimuth loop is off) at the
        state's loop time; the first gains of the azimuth loop switch it on: it takes the north channel over, its
        integrator rate is the signal now."""
        level, azimuth = self._gains(state)
        if azimuth is not None and not state.azimuth_on:
            state.azimuth_on, state.I_N, state.y = True, 0.0, 0.0
        return level, azimuth if state.azimuth_on else None

    def reverse(self, state: CompassState) -> None:
        """Turn the state round for a pass in the other time direction (see the module docstring)."""
        level, azimuth = self._gains(state)
        K1N = (azimuth if state.azimuth_on and azimuth is not None else level)[0]
        V_E, V_N = state.V
        tilt = np.array([-2.0 * K1N * V_N / self.gravity, 2.0 * level[0] * V_E / self.gravity, 0.0])
        state.C_b0_p = (np.eye(3) - skew(tilt)) @ state.C_b0_p
        state.V = -state.V
        state.I_E, state.I_N = -state.I_E, -state.I_N
        state.earth_sign = -state.earth_sign
        T = np.eye(8)
        T[VE, VE] = T[VN, VN] = T[IE, IE] = T[IN, IN] = -1.0
        T[PE, VN] = -2.0 * K1N / self.gravity
        T[PN, VE] = 2.0 * level[0] / self.gravity
        state.P = T @ state.P @ T.T

    def _transition(self, level: tuple, azimuth: tuple | None, earth_sign: float, dt_s: float) -> np.ndarray:
        key = (level, azimuth, earth_sign, dt_s)
        if key == self._F_last[0]:   # already the most recently used
            return self._F_last[1]
        F = self._F_cache.get(key)
        if F is None:
            # the schedule interpolates, so a live step on a ramp adds a key each time: the least recently used go,
            # not the stored-data passes' few (their gains held, each pass direction a sign), which a cleared cache
            # made recompute a matrix exponential per step
            if len(self._F_cache) >= F_CACHE_SIZE:
                self._F_cache.popitem(last=False)
            F = self._F_cache[key] = transition(*level, azimuth is not None, *(azimuth or _NO_AZIMUTH), earth_sign,
                                                self.gravity, self.radius_m, self.omega_cos, self.omega_sin, dt_s)
        else:
            self._F_cache.move_to_end(key)
        self._F_last = (key, F)
        return F

    def error_dynamics(self, level: tuple, azimuth: tuple | None, earth_sign: float = 1.0) -> np.ndarray:
        """A (8, 8) of the linear error model: ẋ = A x for x = (δV_E, δV_N, φ_E, φ_N, φ_U, I_E, I_N, y)."""
        g, R = self.gravity, self.radius_m
        wc, ws = earth_sign * self.omega_cos, earth_sign * self.omega_sin
        K1L, K2L, K3L = level
        north = azimuth if azimuth is not None else level
        A = np.zeros((8, 8))
        A[VE, VE], A[VE, PN] = -K1L, -g
        A[VN, VN], A[VN, PE] = -north[0], g
        A[PE, VN], A[PE, PN], A[PE, PU] = -(1.0 + north[1]) / R, ws, -wc
        A[PN, VE], A[PN, IE], A[PN, PE] = (1.0 + K2L) / R, 1.0, -ws
        A[PU, PE] = wc
        A[IE, VE] = K3L
        if azimuth is None:
            A[PE, IN] = -1.0
            A[IN, VN] = K3L
        else:
            A[PU, YU] = 1.0
            A[YU, YU], A[YU, VN] = -azimuth[2], azimuth[3] / wc
        return A

    def _process_noise(self, dt_s: float) -> np.ndarray:
        """Q (8, 8) of one step of ``dt_s``; cached (every step of a run has the same few), never written to."""
        if dt_s == self._Q_last[0] and self.grade is self._Q_last[1]:
            return self._Q_last[2]
        key = (dt_s, self.grade)   # the pipeline may swap the grade for the louder one the data show
        Q = self._Q_cache.get(key)
        if Q is None:
            if len(self._Q_cache) > 8:
                self._Q_cache.clear()
            Q = self._Q_cache[key] = process_noise(self.grade.acc_vrw_ms_rts**2, self.grade.gyro_arw_rad_rts**2, dt_s)
        self._Q_last = (dt_s, self.grade, Q)
        return Q

    def sigma(self, state: CompassState) -> AttitudeSigma:
        """1-sigma heading and level error (deg): bias limit, azimuth offset and the loop's noise."""
        bias_heading, bias_level = bias_limit_rad(self.bias_grade, self.site.lat, self.gravity)
        azimuth_sigma = self.schedule.sigma_of(self.schedule.azimuth_sigma, state.t_loop_s)
        offset = (2.0 * self.bias_grade.gyro_bias_rad_s / azimuth_sigma if state.azimuth_on and azimuth_sigma > 0
                  else 0.0)
        P = state.P
        heading2 = bias_heading**2 + offset**2 + ESTIMATOR_EFFICIENCY * float(P[PU, PU])
        level2 = bias_level**2 + ESTIMATOR_EFFICIENCY * 0.5 * (float(P[PE, PE]) + float(P[PN, PN]))
        return AttitudeSigma(min(math.degrees(math.sqrt(heading2)), SIGMA_UNKNOWN_DEG),
                             min(math.degrees(math.sqrt(level2)), SIGMA_UNKNOWN_DEG))
