"""In-flight alignment from GNSS (seed 004, docs/algorithms/gnss.md): the VIF and PIF observation sources.

Both live in the inertial frame n0 (the navigation frame at the first fix's place, frozen in
inertial space at the alignment start). GNSS gives the antenna's position and velocity;
C_{n(t)}^{n0} = C_e^{n0} R_z(Ω t) C_n^e(L(t), λ(t)) follows from the fixes (the Earth turned by Ω t
since the start), and so does the inertial position R = C_e^{n0} R_z(Ω t) p^e, whose rate is
dR/dt = C_n^{n0} V^n + ω_ie × R. Hence J(t) = ∫ C_n^{n0} V^n dτ = ΔR − ω_ie^{n0} × ∫ ΔR dτ − T ω_ie^{n0} × R_0
exactly, T = t − t_first: integrals of the velocity come from positions, not from a trapezoid over
fixes that may have gaps. The rest are trapezoids over the observation epochs
(:class:`RunningIntegral`), or over every IMU sample (PIF's ∫ α_v); the GNSS values at an epoch are
the track's linear interpolation between fixes (seed 004 eq. 26-28).

Velocity integration formula (VIF): C_b0^n0 α_v(t) = β_v(t) with α_v = ∫ C_b^{b0} f^b dt (the core's
α) and β_v = C_n^{n0} V^n(t) − V^n(0) + ω_ie^{n0} × J + ∫ C_n^{n0} (−g^n) dt.

Position integration formula (PIF, positions only): integrating VIF once more and dividing by T,
  C_b0^n0 (1/T) ∫ α_v dτ = (1/T) [J(t) + ω_ie^{n0} × ∫ J dτ + ∫∫ g up dσ dτ] − V^n(0).
V^n(0) is a constant common to every pair, which the centred solver absorbs: no velocity is needed.
Whatever is fixed at the first fix (its position error, the lever arm there, α then) enters divided
by T: the solver's drift term c₁/T absorbs it. Position noise enters divided by T too, so early
pairs are weighted down (:meth:`GnssPositionSource.observation_variance`).

Lever arm l^b (IMU to antenna, body axes), compensated exactly in both (the seed leaves it out):
the antenna is C_b0^n0 C_b^{b0} l^b ahead of the IMU in n0 axes, and its velocity over the Earth
C_n^{n0} C_b^n (ω_eb^b × l^b) adds to C_n^{n0} V^n what C_b0^n0 C_b^{b0} (ω_ib^b × l^b) does, up to
terms in Ω² (3e-6 m/s after 300 s). Both are known b0-axes vectors times the unknown attitude, so
they move to the observation side: VIF b = α_v + C_b^{b0}(ω_ib^b × l^b); PIF b = (∫ α_v dτ +
C_b^{b0} l^b)/T. ω_ib^b at an epoch is the gyro's rate the pipeline appends to the GNSS columns.
Each pair is taken less its value at the first fix.
"""
from __future__ import annotations

import copy

import numpy as np

from .coarse import InertialCoarseAlignment
from .conventions import DEG, cross, dcm_from_quat
from .earth import OMEGA_IE, Site, ecef_from_geodetic, normal_gravity, radii
from .sensor_model import SIGMA_UNKNOWN_DEG, bias_limit_rad

GNSS_COLUMNS = 6
"""lat_deg, lon_deg, h_m, vE, vN, vU of the antenna (the pinned GNSS log's columns after t)."""


def C_n_e(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """C_n^e (..., 3, 3): the ENU axes at (lat, lon) rad as columns in ECEF axes."""
    sL, cL, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    zero = np.zeros_like(sL)
    return np.stack((np.stack((-sl, -sL * cl, cL * cl), axis=-1),
                     np.stack((cl, -sL * sl, cL * sl), axis=-1),
                     np.stack((zero, cL, sL), axis=-1)), axis=-2)


def earth_turn(elapsed_s: np.ndarray) -> np.ndarray:
    """C_{e(t)}^{e0} (..., 3, 3): the Earth turned by Ω t about its axis since the start."""
    theta = OMEGA_IE * np.asarray(elapsed_s, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack((np.stack((c, -s, zero), axis=-1), np.stack((s, c, zero), axis=-1),
                     np.stack((zero, zero, one), axis=-1)), axis=-2)


class RunningIntegral:
    """∫ y dt from the first epoch, by the trapezoid rule, over epochs that come in pieces.

    cumsum adds left to right, so the bits are the same whether the epochs come in one call or many.
    """

    def __init__(self, width: int = 3) -> None:
        self.value = np.zeros(width)
        self._last: tuple[float, np.ndarray] | None = None   # (t, y) of the latest epoch

    def extend(self, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The integral (N, width) at each of N new epochs t (N,) s with values y (N, width)."""
        t_prev, y_prev = self._last if self._last is not None else (float(t[0]), y[0])
        steps = np.diff(np.concatenate(([t_prev], t)))[:, None] * 0.5 * (np.concatenate((y_prev[None], y[:-1])) + y)
        integral = np.cumsum(np.concatenate((self.value[None], steps)), axis=0)[1:]
        self.value = integral[-1]
        self._last = (float(t[-1]), y[-1])
        return integral


class GnssSource:
    """What the GNSS sources share: the n0 frame of the first fix, C_{n(t)}^{n0} of the fixes, the lever
    arm, the inertial-position terms of the fixes, and the pairs taken less their first value. Aid
    columns per epoch: the six GNSS values (:data:`GNSS_COLUMNS`) first, ω_ib^b (3, rad/s) from ``rate_column``
    (right after them unless another aid's values come between). ``lever_b``: IMU to antenna, body axes (m).
    ``vel_std_mps``, ``pos_std_m``: the fixes' white noise per axis."""

    aid_width = GNSS_COLUMNS + 3
    sigma_factor = 1.0
    """What the fit's own σ is multiplied by to report an honest σ (calibrated per formula)."""
    drift = False
    """Whether the pairs carry a nuisance term c₁ s_k besides the constant (:meth:`drift_regressor`)."""

    def __init__(self, site: Site, lever_b: np.ndarray | None = None, vel_std_mps: float = 0.1,
                 pos_std_m: float = 2.0, rate_column: int = GNSS_COLUMNS) -> None:
        self.site = site
        self.rate = slice(rate_column, rate_column + 3)
        self.lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
        self.vel_std_mps = vel_std_mps
        self.pos_std_m = pos_std_m
        self._C_e_n0: np.ndarray | None = None
        self._omega_ie_n0 = np.zeros(3)
        self.t_first: float | None = None
        self._first: tuple[np.ndarray, np.ndarray] | None = None    # (b, r) of the first epoch
        self._R_first: np.ndarray | None = None
        self._integrals = {name: RunningIntegral() for name in self._integral_names}
        self._positions = np.zeros((0, 6))
        """Rows (elapsed, lat, lon, h, V_E, V_N) of the latest samples with a fix (:meth:`follow`): where the
        navigation frame is."""

    _integral_names: tuple[str, ...] = ("dR", "g_up")
    """The running integrals the source keeps (∫ΔR dt, ∫ g up dt, …), copied with the source."""

    def __copy__(self) -> GnssSource:
        # the coarse stage's scratch copy runs ahead on pending samples: its integrals must not be these
        clone = object.__new__(type(self))
        clone.__dict__.update(self.__dict__)
        clone._integrals = {name: copy.copy(integral) for name, integral in self._integrals.items()}
        return clone

    def C_n_n0_at(self, elapsed_s: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """C_{n(t)}^{n0} (..., 3, 3) at times ``elapsed_s`` (s since the start) and positions lat, lon (rad); after
        the first epoch."""
        return self._C_e_n0 @ earth_turn(elapsed_s) @ C_n_e(lat, lon)

    def span_s(self, elapsed_s: np.ndarray) -> np.ndarray:
        """T = t − t_first (N,) s of the epochs (0 before the first epoch is known)."""
        return elapsed_s - (self.t_first if self.t_first is not None else elapsed_s)

    def accumulate(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray) -> None:
        """Every integrated IMU sample (time since the start (N,) s, α (N, 3) m/s), before :meth:`vectors`."""

    def follow(self, elapsed_s: np.ndarray, aid: np.ndarray) -> None:
        """The fixes (aid columns as :meth:`vectors` takes them, NaN where none) at every integrated IMU sample (s
        since the start), before :meth:`vectors`. :meth:`C_n_n0` takes the latest sample with a fix at or before the
        time asked, so its answer for a sample does not depend on which samples came in the same call (live as in a
        replay)."""
        rows = np.column_stack((elapsed_s, aid[:, :2] * DEG, aid[:, 2:5]))   # t, lat, lon (rad), h, V_E, V_N
        ok = np.isfinite(rows).all(axis=1)
        if ok.any():   # with the previous call's last row, for the samples before this call's first fix
            self._positions = np.concatenate((self._positions[-1:], rows[ok]))

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(b (M, 3) in b0 axes, r (M, 3) in n0 axes) at M observation epochs ``elapsed_s`` (s since the start),
        from α (M, 3) m/s, C_b^{b0} as quaternions (M, 4) and the aid columns (M, ≥ 9), each less its first value."""
        if aid is None:
            raise ValueError("a GNSS source needs the fixes at every observation")
        if len(elapsed_s) == 0:
            return np.empty((0, 3)), np.empty((0, 3))
        lat, lon = aid[:, 0] * DEG, aid[:, 1] * DEG
        if self._C_e_n0 is None:
            self._C_e_n0 = C_n_e(lat[0], lon[0]).T
            self._omega_ie_n0 = self._C_e_n0 @ np.array([0.0, 0.0, OMEGA_IE])
            self.t_first = float(elapsed_s[0])
        C_n_n0 = self.C_n_n0_at(elapsed_s, lat, lon)
        b, r = self._pairs(elapsed_s, alpha_b0, dcm_from_quat(q_b_b0), aid, C_n_n0)
        if self._first is None:
            self._first = (b[0].copy(), r[0].copy())
        return b - self._first[0], r - self._first[1]

    def _pairs(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, C_b_b0: np.ndarray, aid: np.ndarray,
               C_n_n0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(b, r) at the epochs before the first epoch's values are taken off (:meth:`vectors`)."""
        raise NotImplementedError

    def _inertial_terms(self, elapsed_s: np.ndarray, aid: np.ndarray, C_n_n0: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
        """(J, ∫ g up dt) (M, 3) m and m/s in n0 axes from the first fix on, from the fixes' positions alone.

        J = ∫ C_n^{n0} V^n dt = ΔR − ω_ie × ∫ ΔR dt − T ω_ie × R_0 exactly (R the fixes' inertial position,
        dR/dt = C_n^{n0} V^n + ω_ie × R): no trapezoid over the velocities, so a gap in the fixes costs
        nothing here. ∫ g up: gravity's reaction in n0 axes, whose direction turns at the Earth and
        transport rates only (a trapezoid over a 20-s gap is off by 5e-5 m/s).
        """
        p_e = ecef_from_geodetic(aid[:, 0] * DEG, aid[:, 1] * DEG, aid[:, 2])
        R = (self._C_e_n0 @ earth_turn(elapsed_s) @ p_e[..., None])[..., 0]
        if self._R_first is None:
            self._R_first = R[0].copy()
        dR = R - self._R_first                       # the differences first: R is ~6.4e6 m
        span = self.span_s(elapsed_s)[:, None]
        omega = self._omega_ie_n0
        J = dR - cross(omega, self._integrals["dR"].extend(elapsed_s, dR)) - span * cross(omega, self._R_first)
        g_up = normal_gravity(aid[:, 0] * DEG, aid[:, 2])[:, None] * C_n_n0[:, :, 2]
        return J, self._integrals["g_up"].extend(elapsed_s, g_up)

    def drift_regressor(self, elapsed_s: np.ndarray) -> np.ndarray | None:
        """s_k (M,) of the pairs' nuisance term c₁ s_k, None without one."""
        return None

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        """C_{n(t)}^{n0} at ``elapsed_s``: at the position of the latest sample with a fix at or before it
        (:meth:`follow`: a sample's own, interpolated between fixes by the aiding track), carried on at its
        velocity through a gap in the fixes; the identity before the first observation and before the first fix (a
        later fix, carried back, would make a record before it depend on whether that fix had come: live or replay)."""
        k = int(np.searchsorted(self._positions[:, 0], elapsed_s, side="right")) - 1
        if self._C_e_n0 is None or k < 0:
            return np.eye(3)
        t, lat, lon, h, v_east, v_north = self._positions[k]
        R_M, R_N = radii(lat)
        dt = elapsed_s - t
        return self.C_n_n0_at(np.asarray(elapsed_s), lat + v_north * dt / (R_M + h),
                              lon + v_east * dt / ((R_N + h) * np.cos(lat)))


class GnssVelocitySource(GnssSource):
    """VIF: b = α_v + C_b^{b0}(ω_ib^b × l^b), r = C_n^{n0} V_ant^n + ω_ie^{n0} × J + ∫ g up dt, with
    ∫ C_n^{n0} (ω_ie^n × V^n) dt = ω_ie^{n0} × J from the positions (:meth:`GnssSource._inertial_terms`)."""

    sigma_factor = 1.5
    """The fit's σ assumes white residuals; the IMU noise integrated into α is a random walk, so they are
    not. Seed-004 Monte Carlo (10 seeds, 10-300 s): |error|/σ had median 0.93 and 90th percentile 2.46
    (84 % inside 2σ); this factor brings it to the honest side (docs/algorithms/gnss.md, "The coarse solver")."""

    def _pairs(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, C_b_b0: np.ndarray, aid: np.ndarray,
               C_n_n0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        V_n0 = (C_n_n0 @ aid[:, 3:6, None])[..., 0]
        J, gravity = self._inertial_terms(elapsed_s, aid, C_n_n0)
        lever_velocity = (C_b_b0 @ cross(aid[:, self.rate], self.lever_b)[..., None])[..., 0]
        return alpha_b0 + lever_velocity, V_n0 + cross(self._omega_ie_n0, J) + gravity

    def observation_variance(self, elapsed_s: np.ndarray) -> np.ndarray:
        """μ (N,) m²/s² per axis of the pairs: the velocity noise (equal weights)."""
        return np.full(len(elapsed_s), self.vel_std_mps**2)


class GnssPositionSource(GnssSource):
    """PIF: b = (∫ α_v dτ + C_b^{b0} l^b)/T, r = (J + ω_ie^{n0} × ∫ J dτ + ∫∫ g up)/T (module docstring),
    each from the first fix on. ∫ α_v dτ runs over every IMU sample (:meth:`accumulate`), so a gap in
    the fixes costs nothing. The first fix's position error e₀ enters as −e₀/T: the drift term
    c₁ s_k with s_k = 1/T takes it (:meth:`drift_regressor`)."""

    sigma_factor = 3.0
    """As VIF's, larger: ∫ α_v integrates the IMU noise twice, and the residuals are further from white.
    Seed-004 Monte Carlo (20 seeds, coarse stage alone) at 4.5: |error|/σ had 90th percentiles 1.53
    (5-10 s), 0.40 (10-20 s), 0.42 (20-30 s) and 0.47 (30-60 s); 3.0 keeps 10 s on well inside 2σ."""
    drift = True
    _integral_names = ("dR", "g_up", "J", "g_up_twice", "alpha")

    def __init__(self, site: Site, lever_b: np.ndarray | None = None, vel_std_mps: float = 0.1,
                 pos_std_m: float = 2.0, rate_column: int = GNSS_COLUMNS) -> None:
        super().__init__(site, lever_b, vel_std_mps, pos_std_m, rate_column)
        self._alpha_integral = (np.zeros(0), np.zeros((0, 3)))   # (elapsed, ∫α dτ) at the latest samples

    def accumulate(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray) -> None:
        self._alpha_integral = (elapsed_s, self._integrals["alpha"].extend(elapsed_s, alpha_b0))

    def _pairs(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, C_b_b0: np.ndarray, aid: np.ndarray,
               C_n_n0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        J, gravity = self._inertial_terms(elapsed_s, aid, C_n_n0)
        r = J + cross(self._omega_ie_n0, self._integrals["J"].extend(elapsed_s, J)) + self._integrals[
            "g_up_twice"].extend(elapsed_s, gravity)
        samples, integral = self._alpha_integral
        b = integral[np.searchsorted(samples, elapsed_s)] + C_b_b0 @ self.lever_b
        scale = self.drift_regressor(elapsed_s)[:, None]
        # T = 0 at the first fix: the pair is (0, 0) in the limit, and its weight is zero
        return b * scale, r * scale

    def drift_regressor(self, elapsed_s: np.ndarray) -> np.ndarray:
        """1/T (0 at the first fix, T = 0): the first fix's error over the span."""
        span = self.span_s(elapsed_s)
        return np.divide(1.0, span, out=np.zeros_like(span), where=span > 0.0)

    def observation_variance(self, elapsed_s: np.ndarray) -> np.ndarray:
        """μ (N,) m²/s² per axis of the pairs: position noise over the span, plus the velocity-grade noise the
        integrated IMU errors reach (inf at the first fix: weight 0)."""
        with np.errstate(divide="ignore"):
            return (self.pos_std_m / self.span_s(elapsed_s)) ** 2 + self.vel_std_mps**2


class BodyVelocityPairs:
    """A second pair per fix from an odometer (or DVL) beside the receiver: one velocity seen in both frames.

    The IMU's velocity is C_b^n (V_odo^b − ω_ib^b × l_odo^b) = V_ant^n − C_b^n (ω_ib^b × l_ant^b) (the Earth
    rate's part of ω_eb is 1e-4 m/s at these lever arms), and C_b^n = C_{n0}^{n} C_b0^n0 C_b^{b0}, so
    C_b0^n0 b = r with b = C_b^{b0} (V_odo^b + ω_ib^b × (l_ant^b − l_odo^b)) and r = C_n^{n0} V_ant^n: no constant,
    no drift (the fit takes them with z = 0). Their noise per axis is the fix's and the odometer's together. At
    20 m/s a pair with 0.1-m/s noise sees the heading to 0.3°, against the VIF pairs' accelerations that a
    straight road lacks. An odometer not aligned with the IMU's axes turns the heading by its misalignment.

    odo_column : where V_odo^b (3, body axes, m/s) starts among the aid columns (the rate's are the source's);
    odo_lever_b : the odometer's point from the IMU (body axes, m); odo_std_mps : its noise per axis.
    """

    def __init__(self, odo_column: int, odo_lever_b: np.ndarray, odo_std_mps: float) -> None:
        self.odo = slice(odo_column, odo_column + 3)
        self.odo_lever_b = np.asarray(odo_lever_b, dtype=float)
        self.odo_std_mps = odo_std_mps

    def vectors(self, source: GnssSource, elapsed_s: np.ndarray, q_b_b0: np.ndarray, aid: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(b (M, 3) b0 axes, r (M, 3) n0 axes, μ (M,) m²/s² per axis) at M observation epochs with their aid
        columns (after ``source`` has taken its own pairs there)."""
        lever = cross(aid[:, source.rate], source.lever_b - self.odo_lever_b)
        b = (dcm_from_quat(q_b_b0) @ (aid[:, self.odo] + lever)[..., None])[..., 0]
        C_n_n0 = source.C_n_n0_at(elapsed_s, aid[:, 0] * DEG, aid[:, 1] * DEG)
        r = (C_n_n0 @ aid[:, 3:6, None])[..., 0]
        return b, r, np.full(len(b), source.vel_std_mps**2 + self.odo_std_mps**2)


class GnssCoarseAlignment(InertialCoarseAlignment):
    """The inertial-frame coarse stage with σ from the centred fit's own covariance (manoeuvres, not the
    Earth's rotation, carry the heading here, so the fixed-site σ model does not apply) and the pairs
    weighted by the source's stated noise. With :attr:`body_velocity` each fix gives a second pair, folded after
    its VIF or PIF pair (``n_obs`` counts both)."""

    follows_aid = True   # its source follows the aid at every sample (positions, integrals)

    source: GnssSource
    body_velocity: BodyVelocityPairs | None = None

    def observe(self, elapsed_s: np.ndarray, q_b_b0: np.ndarray, alpha: np.ndarray, aid: np.ndarray | None = None,
                aid_epoch: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.source.accumulate(elapsed_s, alpha)
        self.source.follow(elapsed_s, aid)
        due, outer, pairs = super().observe(elapsed_s, q_b_b0, alpha, aid, aid_epoch)
        if self.body_velocity is None or len(due) == 0:
            return due, outer, pairs
        b, r, mu = self.body_velocity.vectors(self.source, elapsed_s[due], q_b_b0[due], aid[due])
        outer_v, pairs_v = self.solver.prepare(b, r, mu, np.zeros(len(b)), offset=False)
        # each epoch's two pairs one after the other: the fold up to a sample takes both or neither
        return (np.repeat(due, 2), np.stack((outer, outer_v), axis=1).reshape(-1, 3, 3),
                np.stack((pairs, pairs_v), axis=1).reshape(-1, pairs.shape[1]))

    def prepare_pairs(self, elapsed_s: np.ndarray, b: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pairs weighted by the source's stated noise, with its drift regressor if it has one."""
        return self.solver.prepare(b, r, self.source.observation_variance(elapsed_s),
                                   self.source.drift_regressor(elapsed_s))

    def drift_dominates(self, elapsed_s: float) -> bool:
        """Whether the gyro's drift ε t already outweighs the fit's heading noise: the coarse σ only grows from here
        (a MEMS gyro's after some seconds; a navigation-grade gyro's never within an alignment)."""
        covariance = self.solver.covariance()
        return covariance is not None and self._drift2(elapsed_s) >= self.source.sigma_factor**2 * covariance[2, 2]

    def _drift2(self, elapsed_s: float) -> float:
        """(ε t)² (rad²): the fit takes C_b0^n0 as constant; the gyro bias drifts the integrated body attitude C_b^b0
        by ε t on every axis, which a navigation-grade gyro's 0.01°/h keeps under 0.001° and a MEMS gyro's 200°/h
        makes 1.7° in 30 s."""
        return (self.sigma_grade.gyro_bias_rad_s * max(elapsed_s, 0.0)) ** 2

    def sigma(self, elapsed_s: float) -> tuple[float, float]:
        covariance = self.solver.covariance()
        if covariance is None:
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        heading_var, level_var = covariance[2, 2], 0.5 * (covariance[0, 0] + covariance[1, 1])
        if not (heading_var > 0.0 and level_var > 0.0):   # a fit not yet determined (or NaN): not a σ of 0 or NaN
            return SIGMA_UNKNOWN_DEG, SIGMA_UNKNOWN_DEG
        factor, drift2, site = self.source.sigma_factor, self._drift2(elapsed_s), self.source.site
        # until manoeuvres tell them apart, an accelerometer bias ∇ is a tilt of ∇/g (1 mg: 0.06°): the bias limit's
        _, tilt = bias_limit_rad(self.sigma_grade, site.lat, site.gravity)
        heading = np.sqrt(factor**2 * heading_var + drift2)
        level = np.sqrt(factor**2 * level_var + drift2 + tilt**2)
        return min(float(heading / DEG), SIGMA_UNKNOWN_DEG), min(float(level / DEG), SIGMA_UNKNOWN_DEG)
