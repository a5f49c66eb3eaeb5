"""A vehicle that drives: turns and speed changes over the WGS-84 Earth (the aided-mode simulator).

The body's forward axis (y) carries the speed: V^b = [0, v(t), 0] (no side slip), attitude from
Euler profiles (heading with turns, pitch, roll), speed from a profile with raised-cosine changes
(all analytic with their rates: ``motion.AngleProfile`` serves for the speed too). Position
follows from V^n = C_b^n V^b, integrated by RK4 on a fine grid and read back by cubic Hermite
interpolation (its derivative is V^n itself), so the error of the truth is far below any sensor's.

Sensor truth (docs/algorithms/conventions.md; docs/algorithms/odometer.md, "The identity"):
ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n),
f^b = C_n^b [V̇^n + (2 ω_ie^n + ω_en^n) × V^n − g^n],  V̇^n = C_b^n (ω_nb^b × V^b + V̇^b),
with ω_en^n = [−V_N/(R_M+h), V_E/(R_N+h), V_E tan L/(R_N+h)] and normal gravity g(L, h).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from sinsalign.service.align.conventions import cross
from sinsalign.service.align.earth import Site, earth_rate_n, normal_gravity, position_rate, transport_rate_n

from .motion import AngleProfile, AngularMotion

GRID_S = 0.01


def _position_rate(pos: np.ndarray, V_n: np.ndarray) -> np.ndarray:
    return position_rate(V_n, pos[0], pos[2])


@dataclass(frozen=True)
class VehicleMotion:
    """A drive starting at ``start`` (lat, lon in rad, height in m) for ``duration_s`` seconds.

    attitude : heading (turns), pitch and roll profiles. speed : forward speed profile (m/s).
    """

    start: Site
    duration_s: float
    attitude_profiles: AngularMotion = field(default_factory=AngularMotion)
    speed: AngleProfile = field(default_factory=AngleProfile)

    def attitude(self, t: np.ndarray) -> np.ndarray:
        return self.attitude_profiles.attitude(t)

    def velocity_n(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C_b^n, V^b, V^n) at times t: (…, 3, 3), (…, 3), (…, 3)."""
        C_b_n = self.attitude(t)
        v = self.speed.value_and_rate(t)[0]
        V_b = np.stack((np.zeros_like(v), v, np.zeros_like(v)), axis=-1)
        return C_b_n, V_b, (C_b_n @ V_b[..., None])[..., 0]

    @cached_property
    def _grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, positions (lat, lon, h) and their rates on the RK4 grid."""
        t = np.arange(0.0, self.duration_s + 2 * GRID_S, GRID_S)
        V_half = self.velocity_n(np.arange(2 * len(t) - 1) * (GRID_S / 2))[2]   # V^n depends on t only
        pos = np.empty((len(t), 3))
        rates = np.empty((len(t), 3))
        pos[0] = (self.start.lat, self.start.lon, self.start.height_m)
        h = GRID_S
        for k in range(len(t)):
            rates[k] = k1 = _position_rate(pos[k], V_half[2 * k])
            if k + 1 == len(t):
                break
            k2 = _position_rate(pos[k] + h / 2 * k1, V_half[2 * k + 1])
            k3 = _position_rate(pos[k] + h / 2 * k2, V_half[2 * k + 1])
            k4 = _position_rate(pos[k] + h * k3, V_half[2 * k + 2])
            pos[k + 1] = pos[k] + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return t, pos, rates

    def position(self, t: np.ndarray) -> np.ndarray:
        """(lat rad, lon rad, h m) at times t (…, 3), cubic Hermite between grid points."""
        grid_t, pos, rates = self._grid
        t = np.asarray(t, dtype=float)
        k = np.clip(np.floor(t / GRID_S).astype(int), 0, len(grid_t) - 2)
        s = ((t - grid_t[k]) / GRID_S)[..., None]
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * pos[k] + h10 * GRID_S * rates[k] + h01 * pos[k + 1] + h11 * GRID_S * rates[k + 1]

    def body_rate_and_force(self, site: Site, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """C_b^n (…, 3, 3), ω_ib^b (…, 3) rad/s and f^b (…, 3) m/s² at times t (``site`` unused: the start)."""
        C_b_n, omega_nb_b = self.attitude_profiles.attitude_and_rate(t)
        v, v_dot = self.speed.value_and_rate(t)
        zeros = np.zeros_like(v)
        V_b = np.stack((zeros, v, zeros), axis=-1)
        V_b_dot = np.stack((zeros, v_dot, zeros), axis=-1)
        V_n = (C_b_n @ V_b[..., None])[..., 0]
        V_n_dot = (C_b_n @ (cross(omega_nb_b, V_b) + V_b_dot)[..., None])[..., 0]
        lat, _, h = np.moveaxis(self.position(t), -1, 0)
        omega_ie_n = earth_rate_n(lat)
        omega_en_n = transport_rate_n(V_n, lat, h)
        g = normal_gravity(lat, h)
        g_n = np.stack((zeros, zeros, -g), axis=-1)
        f_n = V_n_dot + cross(2.0 * omega_ie_n + omega_en_n, V_n) - g_n
        C_n_b = np.swapaxes(C_b_n, -1, -2)
        omega_ib_b = omega_nb_b + (C_n_b @ (omega_ie_n + omega_en_n)[..., None])[..., 0]
        return C_b_n, omega_ib_b, (C_n_b @ f_n[..., None])[..., 0]


@dataclass(frozen=True)
class MountedMotion:
    """A second IMU (the slave of transfer alignment, seed 002) bolted to a vehicle at a fixed mounting
    C_bs^bm (slave to master body axes), at the master's own point (no lever arm):
    C_bs^n = C_bm^n C_bs^bm, ω_ib^bs = C_bm^bs ω_ib^bm, f^bs = C_bm^bs f^bm. ``vehicle`` is the master's motion."""

    vehicle: VehicleMotion
    C_bs_bm: tuple[tuple[float, float, float], ...]
    lever_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """From the master's point to the slave IMU, master body axes (m)."""

    @property
    def start(self) -> Site:
        return self.vehicle.start

    @property
    def duration_s(self) -> float:
        return self.vehicle.duration_s

    @property
    def mounting(self) -> np.ndarray:
        """C_bs^bm (3, 3)."""
        return np.array(self.C_bs_bm)

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """The slave's C_bs^n (…, 3, 3)."""
        return self.vehicle.attitude(t) @ self.mounting

    def position(self, t: np.ndarray) -> np.ndarray:
        return self.vehicle.position(t)

    def body_rate_and_force(self, site: Site, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The slave's C_bs^n, ω_ib^bs (rad/s) and f^bs (m/s²) at times t: the master's turned by the mounting."""
        C_bm_n, omega_ib_bm, f_bm = self.vehicle.body_rate_and_force(site, t)
        M = self.mounting
        lever = np.asarray(self.lever_m, dtype=float)
        if lever.any():
            h = 1e-4
            omega_dot = (self.vehicle.body_rate_and_force(site, np.asarray(t) + h)[1]
                         - self.vehicle.body_rate_and_force(site, np.asarray(t) - h)[1]) / (2.0 * h)
            f_bm = f_bm + cross(omega_dot, lever) + cross(omega_ib_bm, cross(omega_ib_bm, lever))
        return C_bm_n @ M, omega_ib_bm @ M, f_bm @ M
