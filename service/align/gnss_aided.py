"""In-flight alignment from GNSS velocity (seed 004, alignment-math.md §6): the VIF observation source.

Velocity integration formula, in the inertial frame n0 (the navigation frame at the first fix,
frozen in inertial space): C_b0^n0 α_v(t) = β_v(t) with α_v = ∫ C_b^{b0} f^b dt (the core's α) and
β_v = C_n^{n0} V^n(t) − V^n(0) + ∫ C_n^{n0} (ω_ie^n × V^n − g^n) dt.

GNSS gives the antenna's position and velocity. C_{n(t)}^{n0} = C_e^{n0} R_z(Ω t) C_n^e(L(t), λ(t))
follows from the fixes (the Earth turned by Ω t since the start), and the integral is a trapezoid
over the observation epochs (its integrand changes at the Earth and transport rates only; the
stretch before the first epoch is a constant the centred solver absorbs).

Lever arm l^b (IMU to antenna, body axes), compensated exactly: V_ant^n = V^n + C_b^n (ω_eb^b × l^b),
and C_n^{n0} C_b^n (ω_ib^b × l^b) = C_b0^n0 C_b^{b0} (ω_ib^b × l^b), a known b0-axes vector times
the unknown attitude, so it moves to the observation side:
b = α_v + C_b^{b0} (ω_ib^b × l^b),  r = C_n^{n0} V_ant^n + ∫ C_n^{n0} (ω_ie^n × V_ant^n − g^n) dt,
each less its value at the first epoch. Left out: ω_ie × (C_b^n l) (7e-5 m/s per metre of lever).
ω_ib^b at an epoch is the gyro's rate the pipeline appends to the GNSS columns.
"""
from __future__ import annotations

import numpy as np

from .conventions import DEG, cross, dcm_from_quat
from .earth import OMEGA_IE, Site, normal_gravity

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


class GnssVelocitySource:
    """Observation source of a vehicle with GNSS (VIF). Aid columns per epoch: the six GNSS values
    (:data:`GNSS_COLUMNS`) then ω_ib^b (3, rad/s). ``lever_b``: IMU to antenna, body axes (m)."""

    aid_width = GNSS_COLUMNS + 3

    def __init__(self, site: Site, lever_b: np.ndarray | None = None) -> None:
        self.site = site
        self.lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
        self._C_e_n0: np.ndarray | None = None
        self._omega_ie_n0 = np.zeros(3)
        self._first: tuple[np.ndarray, np.ndarray] | None = None    # (b, r) of the first epoch
        self._integral = np.zeros(3)
        self._last: tuple[float, np.ndarray | None] = (0.0, None)   # (elapsed, integrand) of the latest epoch
        self._fixes = (np.zeros(1), np.zeros(1), np.zeros(1))
        """(elapsed, lat, lon) of the latest call's epochs: where the navigation frame was between them."""

    def _C_n_n0(self, elapsed_s: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return self._C_e_n0 @ earth_turn(elapsed_s) @ C_n_e(lat, lon)

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        if aid is None:
            raise ValueError("a GNSS source needs the fixes at every observation")
        if len(elapsed_s) == 0:
            return np.empty((0, 3)), np.empty((0, 3))
        lat, lon, h = aid[:, 0] * DEG, aid[:, 1] * DEG, aid[:, 2]
        if self._C_e_n0 is None:
            self._C_e_n0 = C_n_e(lat[0], lon[0]).T
            self._omega_ie_n0 = self._C_e_n0 @ np.array([0.0, 0.0, OMEGA_IE])
            self._last = (float(elapsed_s[0]), None)
        C_n_n0 = self._C_n_n0(elapsed_s, lat, lon)
        V_n0 = (C_n_n0 @ aid[:, 3:6, None])[..., 0]
        integrand = cross(self._omega_ie_n0, V_n0) + normal_gravity(lat, h)[:, None] * C_n_n0[:, :, 2]
        t_prev, h_prev = self._last
        h_prev = integrand[0] if h_prev is None else h_prev
        steps = np.diff(np.concatenate(([t_prev], elapsed_s)))[:, None] * 0.5 * (
            np.concatenate((h_prev[None], integrand[:-1])) + integrand)
        # cumsum adds left to right: the same bits whether the epochs come in one call or many
        integral = np.cumsum(np.concatenate((self._integral[None], steps)), axis=0)[1:]
        self._integral = integral[-1]
        self._last = (float(elapsed_s[-1]), integrand[-1])
        self._fixes = (elapsed_s, lat, lon)
        lever_velocity = (dcm_from_quat(q_b_b0) @ cross(aid[:, 6:9], self.lever_b)[..., None])[..., 0]
        b, r = alpha_b0 + lever_velocity, V_n0 + integral
        if self._first is None:
            self._first = (b[0].copy(), r[0].copy())
        return b - self._first[0], r - self._first[1]

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        """C_{n(t)}^{n0} at ``elapsed_s``: the position interpolated between the latest observation epochs
        (held beyond them; the identity before the first)."""
        if self._C_e_n0 is None:
            return np.eye(3)
        elapsed, lat, lon = self._fixes
        return self._C_n_n0(np.asarray(elapsed_s), np.interp(elapsed_s, elapsed, lat),
                            np.interp(elapsed_s, elapsed, lon))
