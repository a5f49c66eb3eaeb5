"""WGS-84 Earth model in the ENU navigation frame (docs/algorithms/conventions.md, "Earth model (WGS-84)";
the fixed site's turn and gravity integral: docs/algorithms/strapdown.md).

Units are SI: latitude in rad, height in m, rates in rad/s, gravity in m/s².
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .conventions import skew

A_M = 6378137.0
"""WGS-84 semi-major axis (m)."""
F = 1.0 / 298.257223563
"""WGS-84 flattening."""
E2 = F * (2.0 - F)
"""First eccentricity squared."""
OMEGA_IE = 7.2921151467e-5
"""Earth rotation rate ω_ie (rad/s)."""
GM = 3.986004418e14
"""Earth's gravitational constant (m³/s²)."""
_GAMMA_E = 9.7803253359
"""Normal gravity at the equator (m/s²)."""
_SOMIGLIANA_K = 0.00193185265241
_M = OMEGA_IE**2 * A_M**2 * (A_M * (1 - F)) / GM


def normal_gravity(lat: float | np.ndarray, height_m: float | np.ndarray = 0.0) -> float | np.ndarray:
    """Magnitude of WGS-84 normal gravity (gravitation plus centripetal) at (lat, h), m/s².

    Somigliana's closed form on the ellipsoid with the second-order free-air correction.
    Scalars in, float out; arrays in, array out.
    """
    s2 = np.sin(lat) ** 2
    g0 = _GAMMA_E * (1.0 + _SOMIGLIANA_K * s2) / np.sqrt(1.0 - E2 * s2)
    g = g0 * (1.0 - 2.0 / A_M * (1.0 + F + _M - 2.0 * F * s2) * height_m + 3.0 / A_M**2 * np.square(height_m))
    return float(g) if np.ndim(g) == 0 else g


def radii(lat: float | np.ndarray) -> tuple[float, float] | tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii of curvature (R_M, R_N), m (floats for a scalar latitude)."""
    w = 1.0 - E2 * np.sin(lat) ** 2
    R_M, R_N = A_M * (1.0 - E2) / w**1.5, A_M / np.sqrt(w)
    return (float(R_M), float(R_N)) if np.ndim(w) == 0 else (R_M, R_N)


def ecef_from_geodetic(lat: np.ndarray, lon: np.ndarray, height_m: np.ndarray) -> np.ndarray:
    """WGS-84 Earth-fixed position (..., 3), m, of geodetic latitude, longitude (rad) and height (m)."""
    sL = np.sin(lat)
    R_N = A_M / np.sqrt(1.0 - E2 * sL**2)
    horizontal = (R_N + height_m) * np.cos(lat)
    return np.stack((horizontal * np.cos(lon), horizontal * np.sin(lon), (R_N * (1.0 - E2) + height_m) * sL), axis=-1)


def earth_rate_n(lat: float | np.ndarray) -> np.ndarray:
    """ω_ie^n = [0, Ω cos L, Ω sin L] (rad/s, ENU), shape (..., 3) for latitudes of shape (...)."""
    lat = np.asarray(lat, dtype=float)
    return OMEGA_IE * np.stack((np.zeros_like(lat), np.cos(lat), np.sin(lat)), axis=-1)


def transport_rate_n(V_n: np.ndarray, lat: float | np.ndarray, height_m: float | np.ndarray) -> np.ndarray:
    """ω_en^n = [−V_N/(R_M+h), V_E/(R_N+h), V_E tan L/(R_N+h)] (rad/s), shape (..., 3)."""
    R_M, R_N = radii(lat)
    V_n = np.asarray(V_n, dtype=float)
    return np.stack((-V_n[..., 1] / (R_M + height_m), V_n[..., 0] / (R_N + height_m),
                     V_n[..., 0] * np.tan(lat) / (R_N + height_m)), axis=-1)


def position_rate(V_n: np.ndarray, lat: float | np.ndarray, height_m: float | np.ndarray) -> np.ndarray:
    """(L̇, λ̇, ḣ) in rad/s, rad/s, m/s of a position moving at V^n (ENU, m/s), shape (..., 3)."""
    R_M, R_N = radii(lat)
    V_n = np.asarray(V_n, dtype=float)
    return np.stack((V_n[..., 1] / (R_M + height_m), V_n[..., 0] / ((R_N + height_m) * np.cos(lat)), V_n[..., 2]),
                    axis=-1)


@dataclass(frozen=True, slots=True)
class Site:
    """A fixed position: latitude and longitude in rad, height in m (WGS-84)."""

    lat: float
    lon: float = 0.0
    height_m: float = 0.0

    @property
    def gravity(self) -> float:
        """Normal gravity magnitude g (m/s²); g^n = [0, 0, -g]."""
        return normal_gravity(self.lat, self.height_m)

    @property
    def omega_ie_n(self) -> np.ndarray:
        return earth_rate_n(self.lat)


def C_n_n0_fixed(lat: float, dt_s: np.ndarray) -> np.ndarray:
    """C_{n(t)}^{n0} for a fixed site: rotation by Ω·dt about the Earth axis u = [0, cos L, sin L].

    ``dt_s`` is the time since the alignment start, shape (...,); returns (..., 3, 3).
    """
    theta = OMEGA_IE * np.asarray(dt_s, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    u = np.array([0.0, np.cos(lat), np.sin(lat)])
    outer = np.outer(u, u)
    return (c[..., None, None] * np.eye(3) + s[..., None, None] * skew(u)
            + (1.0 - c)[..., None, None] * outer)


def earth_turn_integrals(dt_s: np.ndarray) -> np.ndarray:
    """(sin(Ωt)/Ω, (1 − cos Ωt)/Ω, t − sin(Ωt)/Ω) in s, shape (..., 3), of ``dt_s`` (...,) since the start.

    They make E(t) = ∫_0^t C_{n(τ)}^{n0} dτ = P1 I + P2 [u×] + P3 u uᵀ (u the Earth axis, see
    :func:`C_n_n0_fixed`).
    """
    t = np.asarray(dt_s, dtype=float)
    wt = OMEGA_IE * t
    # t - sin(Ωt)/Ω loses all digits for small Ωt in floating point: use its series there
    # products, not powers: numpy's pow differs from a product in the last bit, and the compiled kernels
    # (_kernels.pyx) multiply
    wt2 = wt * wt
    t_minus_sin = np.where(wt > 1e-3, t - np.sin(wt) / OMEGA_IE, t * wt2 / 6.0 * (1.0 - wt2 / 20.0 + wt2 * wt2 / 840.0))
    s_half = np.sin(0.5 * wt)
    one_minus_cos = 2.0 * (s_half * s_half) / OMEGA_IE
    return np.stack((np.sin(wt) / OMEGA_IE, one_minus_cos, t_minus_sin), axis=-1)


def beta_fixed(lat: float, gravity: float, dt_s: np.ndarray) -> np.ndarray:
    """β(t) = -∫_0^t C_{n(τ)}^{n0} g^n dτ = g E(t) Up for a fixed site, in n0 (ENU at t0) axes, m/s.

    Closed form (docs/algorithms/strapdown.md, "The navigation frame's turn and the gravity integral"): the
    local up vector turns east about the Earth axis.
    ``dt_s`` (...,) is the time since the alignment start; returns (..., 3).
    """
    t = np.asarray(dt_s, dtype=float)
    cL, sL = np.cos(lat), np.sin(lat)
    integrals = earth_turn_integrals(t)
    one_minus_cos, t_minus_sin = integrals[..., 1], integrals[..., 2]
    return gravity * np.stack((cL * one_minus_cos, sL * cL * t_minus_sin, t - (cL * cL) * t_minus_sin), axis=-1)
