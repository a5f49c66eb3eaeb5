"""Inertial-frame alignment on a moving base aided by body-frame velocity (seed 003; math §5).

Exact identity: C_b^n(0) α(t) = β(t) with
α = ∫ C_b^{b0} f^b dt − C_b^{b0} V^b(t) + V^b(0) and β = ∫ C_n^{n0} (−g^n + ω_ie^n × V^n) dt
(signs as the fixed-site source: with V = 0 they are ∫ C f and −∫ C g). β needs V^n = C_b^n V^b,
hence an attitude, and C_{n(t)}^{n0} turns with the Earth rate *and* the transport rate of the
position the velocity carries. The multistage method: level 1 is the traditional V^b model
(β = −∫ C_n^{n0} g^n, no ω_ie × V^n term, no transport); each further level recomputes β over the
stored window with the previous level's attitude (dual-velocity model) and solves again.
Each level's error shrinks by about four; the first aiding sample V^b(0) is one noisy constant in
every α, so the solver must absorb constants common to all pairs (``CentredWahba``).

This module holds the offline core over a stored window; the streaming pipeline around it (a
bounded window, levels in slices, the live daemon) is the aided-mode issue's next step.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .compass import rotation_matrix
from .conventions import cross, dcm_from_quat
from .earth import Site, earth_rate_n, normal_gravity, position_rate, transport_rate_n
from .solvers import make_solver


@dataclass(frozen=True, slots=True)
class VelocityWindow:
    """Stored epochs: time since the start (N,) s, ∫C_b^{b0} f^b dt (N, 3) m/s, C_b^{b0} (N, 3, 3),
    aiding V^b (N, 3) m/s at the epochs, and V^b at the start (3,)."""

    elapsed_s: np.ndarray
    alpha_f: np.ndarray
    C_b_b0: np.ndarray
    V_b: np.ndarray
    V_b0: np.ndarray

    def observation_vectors(self) -> np.ndarray:
        """α (N, 3): ∫ C f − C_b^{b0} V^b + V^b(0)."""
        return self.alpha_f - (self.C_b_b0 @ self.V_b[..., None])[..., 0] + self.V_b0


def reference_vectors(window: VelocityWindow, start: Site, C_b0_n0: np.ndarray | None) -> np.ndarray:
    """β (N, 3) over the window: traditional (``C_b0_n0`` None) or dual-velocity with that attitude.

    Trapezoidal integration between epochs; position and C_{n}^{n0} advance with the velocity
    V^n = C_{n0}^{n} C_b0^n0 C_b^{b0} V^b (Earth rate plus transport rate).
    """
    pos = np.array([start.lat, start.lon, start.height_m])
    C_n_n0 = np.eye(3)
    beta = np.zeros(3)
    out = np.empty((len(window.elapsed_s), 3))
    previous = None
    t_prev = 0.0
    for k, t in enumerate(window.elapsed_s):
        lat, h = pos[0], pos[2]
        omega_ie_n = earth_rate_n(lat)
        minus_g_n = np.array([0.0, 0.0, normal_gravity(lat, h)])
        if C_b0_n0 is None:
            V_n = np.zeros(3)
            integrand = C_n_n0 @ minus_g_n
        else:
            V_n = C_n_n0.T @ C_b0_n0 @ window.C_b_b0[k] @ window.V_b[k]
            integrand = C_n_n0 @ (minus_g_n + cross(omega_ie_n, V_n))
        if previous is None:   # the first interval starts at the alignment start: hold its integrand
            previous = integrand
        beta = beta + 0.5 * (t - t_prev) * (previous + integrand)
        out[k] = beta
        step = window.elapsed_s[k + 1] - t if k + 1 < len(window.elapsed_s) else 0.0
        C_n_n0 = C_n_n0 @ rotation_matrix((omega_ie_n + transport_rate_n(V_n, lat, h)) * step)
        pos = pos + step * position_rate(V_n, lat, h)
        previous, t_prev = integrand, t
    return out


def multistage_alignment(window: VelocityWindow, start: Site, levels: int = 10,
                         solver: str = "centred") -> list[np.ndarray]:
    """C_{b0}^{n0} (3, 3) after each level: level 1 traditional, then dual-velocity re-runs."""
    alpha = window.observation_vectors()
    estimates: list[np.ndarray] = []
    for _ in range(levels):
        beta = reference_vectors(window, start, estimates[-1] if estimates else None)
        s = make_solver(solver)
        s.fold(*s.prepare(alpha, beta, np.ones(len(alpha))))
        estimates.append(dcm_from_quat(s.quaternion()))
    return estimates
