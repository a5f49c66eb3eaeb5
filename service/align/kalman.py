"""Error-state Kalman filter of the moving-base fine stage, with pluggable measurements.

Navigation lives in the inertial chain like the compass stage: the attitude is
C_b^n(t) = C_{n0}^{n(t)} · C_b0^n0 · C_{b(t)}^{b0}, with C_{b(t)}^{b0} and the specific-force
integral α from the coarse stage's strapdown integrator (every IMU sample, coning and sculling
corrected) and the filter owning the constant C_b0^n0, velocity V^n (ENU, m/s), position
(lat, lon rad, h m) and C_{n(t)}^{n0}, advanced one control step at a time:
  V^n ← V^n + C_{n0}^{n} C_b0^n0 Δα + (g^n − (2ω_ie^n + ω_en^n) × V^n) Δt,
  C_n^{n0} ← C_n^{n0} exp([(ω_ie^n + ω_en^n) Δt ×]),  position by its rate.
Here n0 is the local level frame at the start of the fine stage.

Error states (ENU, ψ-angle form: Ĉ_b^n = (I − [φ×]) C_b^n, V̂ = V + δV, p̂ = p + δp):
φ (3, rad), δV (3, m/s), gyro bias ε (3, rad/s), accelerometer bias ∇ (3, m/s²), position δp
(3, m, ENU), then the extra states of each measurement (odometer scale factor and lever arm, later
transfer-alignment mounting). φ̇ = −ω_in^n × φ − C_b^n ε,  δV̇ = f^n × φ + C_b^n ∇ − (2ω_ie + ω_en) × δV,
δṗ = δV (the curvature terms, δV/R and g/R δp, are below 1e-6 of these over an alignment).
The biases and extra states are whole values, not fed back into the IMU data: their mean drives φ
and δV at each prediction, and φ, δV, δp are injected into the navigation after every prediction
and update, so the filter's mean of them stays zero.

A measurement (:class:`Measurement`) gives the innovation y − h(x̂), its Jacobian and noise; the
filter gates it (χ² of the innovation against its covariance) and counts what it rejects.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .compass import rotation_matrix
from .conventions import DEG, cross, dcm_from_quat, quat_from_dcm, rotvec_from_quat, skew, wrap_pi
from .earth import earth_rate_n, normal_gravity, position_rate, radii, transport_rate_n
from .sensor_model import AttitudeSigma, SensorGrade

PHI, DV, GYRO_BIAS, ACC_BIAS, POS = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)
CORE_STATES = 15
ROTATION_NOISE_RAD_RTS = 1.2e-6
"""Attitude random walk (rad/√s, 0.004°/√h) added to the gyro's: what the linear model misses at 2-g
turns (discretisation, second-order terms). Without it the seed-003 Monte Carlo at 60 and 80 m/s had
σ shrinking through a turn faster than the error (2-3 runs in 20 reported converged beyond 3σ);
with it none do, and the 600-s heading MAE goes from 0.013° to 0.033° (bound 0.1°)."""
BIAS_INSTABILITY_FRACTION = 0.1
"""Random walk of each bias per hour, as a fraction of its 1-sigma value (slow, honest drift)."""


def enu_to_geodetic_step(d_enu_m: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(Δlat rad, Δlon rad, Δh m) of a small ENU offset (3,) m at ``position`` (lat rad, lon rad, h m)."""
    return position_rate(d_enu_m, position[0], position[2])


def geodetic_to_enu_step(d_position: np.ndarray, position: np.ndarray) -> np.ndarray:
    """ENU offset (3,) m of a small (Δlat rad, Δlon rad, Δh m) at ``position``: the inverse of the above. Δlon
    is taken the short way round (a fix and a position on either side of ±180° are close)."""
    R_M, R_N = radii(position[0])
    h = position[2]
    return np.array([wrap_pi(d_position[1]) * (R_N + h) * np.cos(position[0]), d_position[0] * (R_M + h),
                     d_position[2]])


def moved(position: np.ndarray, d_position: np.ndarray) -> np.ndarray:
    """``position`` (lat rad, lon rad, h m) moved by (Δlat, Δlon, Δh), its longitude kept in [-π, π) like a fix's."""
    out = position + d_position
    out[1] = wrap_pi(out[1])
    return out


@dataclass(slots=True)
class Navigation:
    """What a measurement needs of the current solution.

    C_b_n (3, 3), V_n (3,) m/s ENU, position (3,) lat rad / lon rad / h m, omega_eb_b (3,) rad/s
    the body rate over the Earth in body axes (for lever arms).
    """

    C_b_n: np.ndarray
    V_n: np.ndarray
    position: np.ndarray
    omega_eb_b: np.ndarray


class Measurement(Protocol):
    """One kind of aiding measurement of the filter."""

    name: str
    extra_states: int
    """How many states of its own the measurement adds (scale factors, lever arms, …)."""

    def initial_extra(self) -> tuple[np.ndarray, np.ndarray]:
        """(initial values (extra_states,), their 1-sigma (extra_states,))."""
        ...

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(innovation y − h(x̂) (m,), H_core (m, CORE_STATES), H_extra (m, extra_states), R (m, m)).

        H_core = −∂h/∂(core errors): the truth is the navigation less its error (φ, δV, …), so the innovation
        is H_core times the error. H_extra = ∂h/∂extra: the extra states hold whole values."""
        ...


CONTRADICTED_S = 5.0
"""Filter time (s) of unbroken gate rejections of one measurement kind after which the filter's σ is not believed:
longer than a receiver's glitch (a second or two), short against an alignment."""


@dataclass(slots=True)
class MeasurementCounters:
    accepted: int = 0
    rejected: int = 0


class ErrorStateFilter:
    """The fine stage: navigation in the inertial chain plus the error-state covariance.

    grade : datasheet sensor figures (process noise and the biases' prior).
    measurements : the measurement models this filter takes, by name.
    gate_chi2 : innovations with a larger normalised square are rejected (counted).
    """

    def __init__(self, grade: SensorGrade, measurements: list[Measurement], gate_chi2: float = 16.3) -> None:
        self.grade = grade
        self.gate_chi2 = gate_chi2
        self.measurements = {m.name: m for m in measurements}
        self._extra: dict[str, slice] = {}
        n = CORE_STATES
        for m in measurements:
            self._extra[m.name] = slice(n, n + m.extra_states)
            n += m.extra_states
        self.n_states = n
        self.counters = {m.name: MeasurementCounters() for m in measurements}
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        self.C_b0_n0: np.ndarray | None = None
        self.C_n_n0 = np.eye(3)
        self.V_n = np.zeros(3)
        self.position = np.zeros(3)
        self.omega_eb_b = np.zeros(3)
        self._C_b_b0 = np.eye(3)
        self.elapsed_s = 0.0
        self._rejecting_since: dict[str, float] = {}   # kind → elapsed_s of the first of its unbroken rejections
        self.log_likelihood = 0.0
        """Σ over the updates since :meth:`start` of ln N(ν; 0, S), ν'S⁻¹ν capped at the gate (a glitch costs
        what a rejection costs, not its size): how well this filter's model predicted its data."""

    @property
    def active(self) -> bool:
        return self.C_b0_n0 is not None

    def start(self, C_b_n: np.ndarray, C_b_b0: np.ndarray, V_n: np.ndarray, position: np.ndarray,
              tilt_sigma_rad: float, heading_sigma_rad: float, velocity_sigma_mps: float,
              velocity_from_attitude: bool = True,
              extra: dict[str, tuple[np.ndarray, np.ndarray]] | None = None, position_sigma_m: float = 1.0,
              measurements: Sequence[Measurement] = ()) -> None:
        """Hand-over from the coarse stage: attitude C_b^n (3, 3) of the body attitude C_b^{b0}, V^n,
        position, and their 1-sigma errors.

        ``velocity_from_attitude``: V^n is a body velocity turned by this attitude (V̂ = Ĉ_b^n V^b), so
        its error holds the attitude's, δV = [V×] φ + noise: the covariance says so, or else the
        first body-velocity reading would "see" the heading error and collapse its σ at once.
        ``extra``: (values, 1-sigma) of a measurement's own states known from the coarse stage, in place
        of the measurement's priors. ``position_sigma_m``: 1-sigma of the position per ENU axis.
        ``measurements``: models whose reference is known only now (a mounting, a lever arm from the coarse stage),
        each in place of the configured one of its name (with as many states of its own).
        """
        for m in measurements:
            if self.measurements[m.name].extra_states != m.extra_states:
                raise ValueError(f"measurement {m.name}: {m.extra_states} states in place of "
                                 f"{self.measurements[m.name].extra_states}")
            self.measurements[m.name] = m
        self.C_n_n0 = np.eye(3)
        self.C_b0_n0 = C_b_n @ C_b_b0.T
        self._C_b_b0 = C_b_b0
        self.V_n = np.asarray(V_n, dtype=float).copy()
        self.position = np.asarray(position, dtype=float).copy()
        g = self.grade
        sigma = np.concatenate(([tilt_sigma_rad] * 2, [heading_sigma_rad], [velocity_sigma_mps] * 3,
                                [g.gyro_bias_rad_s] * 3, [g.acc_bias_ms2] * 3, [position_sigma_m] * 3))
        self.x = np.zeros(self.n_states)
        extra_sigma = []
        for name, m in self.measurements.items():
            values, sigmas = (extra or {}).get(name) or m.initial_extra()
            self.x[self._extra[name]] = values
            extra_sigma.append(sigmas)
        self.P = np.diag(np.concatenate([sigma, *extra_sigma]) ** 2)
        if velocity_from_attitude:
            coupling = skew(self.V_n)
            self.P[DV, PHI] = coupling @ self.P[PHI, PHI]
            self.P[PHI, DV] = self.P[DV, PHI].T
            self.P[DV, DV] += coupling @ self.P[PHI, PHI] @ coupling.T
        self.elapsed_s = 0.0
        self._rejecting_since.clear()
        self.log_likelihood = 0.0

    def _rates(self, V_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lat, h = self.position[0], self.position[2]
        return earth_rate_n(lat), transport_rate_n(V_n, lat, h)

    def predict(self, dalpha_b0: np.ndarray, dt_s: float, C_b_b0: np.ndarray) -> None:
        """One control step: Δα (3,) m/s in b0 axes over ``dt_s``, ending at body attitude C_b^{b0}."""
        if dt_s <= 0.0:
            return
        omega_ie, omega_en = self._rates(self.V_n)
        omega_in = omega_ie + omega_en
        C_n_n0_mid = self.C_n_n0 @ rotation_matrix(0.5 * dt_s * omega_in)
        dv_f_n = C_n_n0_mid.T @ self.C_b0_n0 @ dalpha_b0
        g_n = np.array([0.0, 0.0, -normal_gravity(self.position[0], self.position[2])])
        V_new = self.V_n + dv_f_n + (g_n - cross(2.0 * omega_ie + omega_en, self.V_n)) * dt_s
        self.position = moved(self.position, dt_s * position_rate(0.5 * (self.V_n + V_new), self.position[0],
                                                                  self.position[2]))
        self.V_n = V_new
        self.C_n_n0 = self.C_n_n0 @ rotation_matrix(dt_s * omega_in)
        step = rotvec_from_quat(quat_from_dcm(self._C_b_b0.T @ C_b_b0))
        C_b_n = C_n_n0_mid.T @ self.C_b0_n0 @ C_b_b0
        self.omega_eb_b = step / dt_s - C_b_n.T @ omega_ie
        # the biases act through the attitude over the step: its middle (in a 12°/s roll the end's was 5e-5 m/s
        # per 0.1 s off for a 5-mg bias, half a precise master's velocity noise)
        C_b_n_mid = C_n_n0_mid.T @ self.C_b0_n0 @ self._C_b_b0 @ rotation_matrix(0.5 * step)
        self._C_b_b0 = C_b_b0
        F = np.zeros((self.n_states, self.n_states))
        F[PHI, PHI] = -skew(omega_in)
        F[PHI, GYRO_BIAS] = -C_b_n_mid
        F[DV, PHI] = skew(dv_f_n / dt_s)
        F[DV, DV] = -skew(2.0 * omega_ie + omega_en)
        F[DV, ACC_BIAS] = C_b_n_mid
        F[POS, DV] = np.eye(3)
        Fdt = F * dt_s
        Phi = np.eye(self.n_states) + Fdt + 0.5 * Fdt @ Fdt
        self.x = Phi @ self.x
        self.P = Phi @ self.P @ Phi.T + self._Q(dt_s)
        self.elapsed_s += dt_s
        self._inject()

    def _Q(self, dt_s: float) -> np.ndarray:
        g = self.grade
        walk = BIAS_INSTABILITY_FRACTION**2 / 3600.0
        q = np.zeros(self.n_states)
        q[PHI] = g.gyro_arw_rad_rts**2 + ROTATION_NOISE_RAD_RTS**2
        q[DV] = g.acc_vrw_ms_rts**2
        q[GYRO_BIAS] = walk * g.gyro_bias_rad_s**2
        q[ACC_BIAS] = walk * g.acc_bias_ms2**2
        return np.diag(q * dt_s)

    def _inject(self) -> None:
        """Move φ, δV and δp into the navigation (C_b^n ← exp([φ×]) Ĉ_b^n, V ← V̂ − δV, p ← p̂ − δp); zero them."""
        phi = self.x[PHI]
        self.C_b0_n0 = self.C_n_n0 @ rotation_matrix(phi) @ self.C_n_n0.T @ self.C_b0_n0
        self.V_n = self.V_n - self.x[DV]
        self.position = moved(self.position, -enu_to_geodetic_step(self.x[POS], self.position))
        self.x[PHI] = 0.0
        self.x[DV] = 0.0
        self.x[POS] = 0.0

    def navigation(self) -> Navigation:
        return Navigation(self.C_n_n0.T @ self.C_b0_n0 @ self._C_b_b0, self.V_n, self.position, self.omega_eb_b)

    def update(self, name: str, value: np.ndarray) -> bool:
        """Fold one measurement of kind ``name``; False (and counted) if the χ² gate rejects it."""
        m, extra = self.measurements[name], self._extra[name]
        nu, H_core, H_extra, R = m.model(self.navigation(), self.x[extra], np.asarray(value, dtype=float))
        H = np.zeros((len(nu), self.n_states))
        H[:, :CORE_STATES] = H_core
        H[:, extra] = H_extra
        PHt = self.P @ H.T
        S = H @ PHt + R
        nis = float(nu @ np.linalg.solve(S, nu))
        self.log_likelihood -= 0.5 * ((nis if nis <= self.gate_chi2 else self.gate_chi2)
                                    + np.linalg.slogdet(2.0 * np.pi * S)[1])
        if not nis <= self.gate_chi2:
            self.counters[name].rejected += 1
            self._rejecting_since.setdefault(name, self.elapsed_s)
            return False
        self._rejecting_since.pop(name, None)
        K = np.linalg.solve(S, PHt.T).T
        self.x = self.x + K @ nu
        I_KH = np.eye(self.n_states) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T
        self.P = 0.5 * (self.P + self.P.T)
        self.counters[name].accepted += 1
        self._inject()
        return True

    def attitude(self, C_b_b0: np.ndarray, since_step_s: float = 0.0) -> np.ndarray:
        """C_b^n (3, 3) of the body attitude C_b^{b0} taken ``since_step_s`` after the last control step (the
        navigation frame turns on meanwhile: 7e-6 rad in a 0.1-s step, at the Earth rate alone)."""
        C_n_n0 = self.C_n_n0
        if since_step_s:
            omega_ie, omega_en = self._rates(self.V_n)
            C_n_n0 = C_n_n0 @ rotation_matrix((omega_ie + omega_en) * since_step_s)
        return C_n_n0.T @ self.C_b0_n0 @ C_b_b0

    def contradicted(self) -> tuple[str, float] | None:
        """(kind, s) of a measurement kind whose every update the gate has rejected for at least
        :data:`CONTRADICTED_S` of filter time, the longest such run; None if none has. A glitch is rejected for
        about its own length; a filter whose model does not fit its data (an IMU far worse than its datasheet:
        a MEMS gyro stated as tactical rejects 97 % of its fixes, 6° off under σ 0.08°) rejects on."""
        runs = [(name, self.elapsed_s - since) for name, since in self._rejecting_since.items()]
        longest = max(runs, key=lambda run: run[1], default=None)
        return longest if longest is not None and longest[1] >= CONTRADICTED_S else None

    @property
    def sigma(self) -> AttitudeSigma:
        """1-sigma heading and level (the worse of the two level axes: flying straight, the roll axis is the
        weak one, and their mean claimed up to √2 too much) in degrees."""
        P = self.P
        return AttitudeSigma(float(np.sqrt(P[2, 2])) / DEG, float(np.sqrt(max(P[0, 0], P[1, 1]))) / DEG)

    def set_covariance(self, states: np.ndarray, block: np.ndarray) -> None:
        """Replace the covariance of ``states`` (indices) with ``block`` (a prior that knows their correlations)."""
        self.P[np.ix_(states, states)] = block

    def extra_slice(self, name: str) -> slice:
        """Where measurement ``name``'s extra states sit in the state vector."""
        return self._extra[name]

    def extra(self, name: str) -> np.ndarray:
        """The current extra states of measurement ``name``."""
        return self.x[self._extra[name]].copy()


class BodyVelocity:
    """Odometer / DVL measurement: the velocity over ground of a point at lever arm l^b, in body axes.

    h = (1 + k) Ĉ_n^b V^n + ω_eb^b × l^b (scale factor k on the forward reading, lever arm l^b).
    std_mps : 1-sigma white noise per axis. lever_b : the configured lever arm (m). scale_sigma :
    prior 1-sigma of k (0: k not estimated). lever_sigma_m : prior of l^b per axis (0: not estimated).
    """

    name = "odo"

    def __init__(self, std_mps: float, lever_b: np.ndarray | None = None, scale_sigma: float = 0.0,
                 lever_sigma_m: float = 0.0) -> None:
        self.std_mps = std_mps
        self.lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
        self.scale = scale_sigma > 0.0
        self.lever = lever_sigma_m > 0.0
        self._prior = ([0.0] if self.scale else []) + (list(self.lever_b) if self.lever else [])
        self._sigma = ([scale_sigma] if self.scale else []) + ([lever_sigma_m] * 3 if self.lever else [])
        self.extra_states = len(self._prior)

    def initial_extra(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self._prior, dtype=float), np.array(self._sigma, dtype=float)

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        k = extra[0] if self.scale else 0.0
        lever = extra[int(self.scale):] if self.lever else self.lever_b
        C_n_b = nav.C_b_n.T
        u = C_n_b @ nav.V_n
        h = u * (1.0 + k) + cross(nav.omega_eb_b, lever)
        H_core = np.zeros((3, CORE_STATES))
        H_core[:, PHI] = (1.0 + k) * C_n_b @ skew(nav.V_n)
        H_core[:, DV] = -(1.0 + k) * C_n_b
        H_extra = np.zeros((3, self.extra_states))
        if self.scale:
            H_extra[:, 0] = u
        if self.lever:
            H_extra[:, int(self.scale):] = skew(nav.omega_eb_b)
        return value - h, H_core, H_extra, np.eye(3) * self.std_mps**2


def antenna_lever_velocity(C_b_n: np.ndarray, omega_ib_b: np.ndarray, lat: float, lever_b: np.ndarray) -> np.ndarray:
    """C_b^n (ω_eb^b × l^b) (3,) m/s: how much faster than the IMU an antenna at lever arm l^b (body axes, m)
    moves over the Earth, from the gyro rate ω_ib^b (rad/s) at latitude ``lat`` (rad)."""
    omega_eb_b = omega_ib_b - C_b_n.T @ earth_rate_n(lat)
    return C_b_n @ cross(omega_eb_b, lever_b)


class AntennaMeasurement:
    """A GNSS fix of an antenna at lever arm ``lever_b`` (IMU to antenna, body axes, m) with white noise
    ``std`` per ENU axis; the lever arm is known (no states of its own). ``name`` overrides the kind's
    (a master INS's velocity is a fix of the same form)."""

    extra_states = 0

    def __init__(self, std: float, lever_b: np.ndarray | None = None, name: str | None = None) -> None:
        if name is not None:
            self.name = name
        self.std = std
        self.lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)

    def initial_extra(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros(0)


class GnssVelocity(AntennaMeasurement):
    """GNSS velocity: h = V^n + C_b^n (ω_eb^b × l^b), ENU m/s (``std`` in m/s).

    The value given to :meth:`ErrorStateFilter.update` is (vE, vN, vU, ω_ib^b (3) rad/s): the fix
    and the gyro rate at its time.
    """

    name = "gnss_vel"

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        innovation, H_core, R = point_velocity(nav, value, self.lever_b, self.std)
        return innovation, H_core, np.zeros((3, 0)), R


def point_velocity(nav: Navigation, value: np.ndarray, lever_b: np.ndarray, std: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(innovation, H_core, R) of a measured velocity (``value``: vE, vN, vU, then ω_ib^b (3) rad/s) of the point at
    ``lever_b`` (body axes, m), white noise ``std`` (m/s) per ENU axis."""
    lever_velocity = antenna_lever_velocity(nav.C_b_n, value[3:6], nav.position[0], lever_b)
    H_core = np.zeros((3, CORE_STATES))
    H_core[:, PHI] = -skew(lever_velocity)
    H_core[:, DV] = -np.eye(3)
    return value[:3] - nav.V_n - lever_velocity, H_core, np.eye(3) * std**2


class LeverVelocity(AntennaMeasurement):
    """The velocity of a point at a lever arm l^b that is not known well (transfer alignment: the master's point
    seen from the slave): h = V^n + C_b^n (ω_eb^b × l^b) with l^b (3, body axes, m) as extra states, whole values,
    prior ``lever_b`` ± ``lever_sigma_m`` per axis. The body's turns make it observable (∂h/∂l = C_b^n [ω_eb^b×]);
    left out, a 1-m lever arm rolled at 10°/s reads as 0.1-0.2 m/s of velocity error and tilts the estimate."""

    name = "gnss_vel"
    extra_states = 3

    def __init__(self, std: float, lever_b: np.ndarray | None = None, lever_sigma_m: float = 1.0,
                 name: str | None = None) -> None:
        super().__init__(std, lever_b, name)
        self.lever_sigma_m = lever_sigma_m

    def initial_extra(self) -> tuple[np.ndarray, np.ndarray]:
        return self.lever_b.copy(), np.full(3, self.lever_sigma_m)

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        innovation, H_core, R = point_velocity(nav, value, extra, self.std)
        omega_eb_b = value[3:6] - nav.C_b_n.T @ earth_rate_n(nav.position[0])
        return innovation, H_core, nav.C_b_n @ skew(omega_eb_b), R


class GnssPosition(AntennaMeasurement):
    """GNSS position: h = p + C_b^n l^b, as an ENU offset (m) from the navigation's position (``std`` in m).
    The value is (lat rad, lon rad, h m) of the fix."""

    name = "gnss_pos"

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        lever_n = nav.C_b_n @ self.lever_b
        H_core = np.zeros((3, CORE_STATES))
        H_core[:, PHI] = -skew(lever_n)
        H_core[:, POS] = -np.eye(3)
        innovation = geodetic_to_enu_step(value[:3] - nav.position, nav.position) - lever_n
        return innovation, H_core, np.zeros((3, 0)), np.eye(3) * self.std**2


class MasterAttitude:
    """Attitude matching against a master INS (transfer alignment, seed 002), with the mounting as extra states.

    The mounting is M = C_bs^bm = M_ref exp([μ×]): ``M_ref`` from the large-angle phase (the model the filter
    starts with, :meth:`ErrorStateFilter.start`), μ (3, rad, slave body axes) the filter's whole-value correction.
    The value is the master's quaternion of C_bm^n; the innovation is the small rotation
    E = C_bm^n M_ref exp([μ̂×]) Ĉ_bs^{nT} ≈ I + [(φ + C_bs^n (μ̂ − μ))×], so H_φ = I and H_μ = −C_bs^n.
    std_rad : the master's attitude noise per axis; mount_sigma_rad : prior 1-sigma of μ per axis.
    """

    name = "master_att"
    extra_states = 3

    def __init__(self, std_rad: float, mount_sigma_rad: float = 0.01, M_ref: np.ndarray | None = None) -> None:
        self.std_rad = std_rad
        self.mount_sigma_rad = mount_sigma_rad
        self.M_ref = np.eye(3) if M_ref is None else np.asarray(M_ref, dtype=float)

    def initial_extra(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(3), np.full(3, self.mount_sigma_rad)

    def mounting(self, mu: np.ndarray) -> np.ndarray:
        """C_bs^bm (3, 3) of the extra states μ."""
        return self.M_ref @ rotation_matrix(mu)

    def model(self, nav: Navigation, extra: np.ndarray, value: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        E = dcm_from_quat(value[:4]) @ self.mounting(extra) @ nav.C_b_n.T
        H_core = np.zeros((3, CORE_STATES))
        H_core[:, PHI] = np.eye(3)
        # H_μ at C_bm^n M_ref as the filter estimates it, Ĉ_bs^n exp(−[μ̂×]), not at Ĉ_bs^n: an update's correction
        # turns φ̂ and μ̂ together, the slave's attitude with it, and a Jacobian that turns while the body does not
        # reads their shared heading error as observed (driving straight, attitude matching alone would take a 30°
        # prior to 1.5° in a few updates, where it tells nothing)
        H_mu = -nav.C_b_n @ rotation_matrix(-extra)
        return rotvec_from_quat(quat_from_dcm(E)), H_core, H_mu, np.eye(3) * self.std_rad**2
