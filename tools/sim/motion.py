"""Angular motion of a base that does not translate: static, swinging, turntable positions.

Each Euler angle (heading clockwise from North, pitch, roll; rad) is a centre that steps between
turntable positions with raised-cosine transitions, plus a sum of sinusoids
A sin(2π f t + φ) (the swing model of seed 000). Angles and their rates are analytic, so body
rates follow exactly from the Euler-angle kinematics.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sinsalign.service.align.conventions import dcm_from_euler
from sinsalign.service.align.earth import Site


@dataclass(frozen=True, slots=True)
class Sinusoid:
    """A sin(2π f t + phase) + nothing else; amplitude and phase in rad, frequency in Hz."""

    amplitude: float
    freq_hz: float
    phase: float = 0.0


@dataclass(frozen=True, slots=True)
class AngleProfile:
    """One Euler angle (rad): a centre, optional turntable steps, optional sinusoids, an optional constant rate.

    ``steps`` are (t_start_s, new_centre) pairs in time order; each move takes
    ``transition_s`` with a raised-cosine profile (rate continuous at its ends). ``rate`` (rad/s) turns the
    centre on from t = 0 (a table rotating continuously).
    """

    centre: float = 0.0
    sinusoids: tuple[Sinusoid, ...] = ()
    steps: tuple[tuple[float, float], ...] = ()
    transition_s: float = 10.0
    rate: float = 0.0

    def value_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle (rad) and its time derivative (rad/s) at times t (s)."""
        t = np.asarray(t, dtype=float)
        value = self.centre + self.rate * t
        rate = np.full_like(t, self.rate)
        previous = self.centre
        for t_start, target in self.steps:
            x = np.clip((t - t_start) / self.transition_s, 0.0, 1.0)
            inside = (x > 0.0) & (x < 1.0)
            value += (target - previous) * 0.5 * (1.0 - np.cos(np.pi * x))
            rate += np.where(inside, (target - previous) * 0.5 * np.pi / self.transition_s * np.sin(np.pi * x), 0.0)
            previous = target
        for s in self.sinusoids:
            w = 2.0 * np.pi * s.freq_hz
            value += s.amplitude * np.sin(w * t + s.phase)
            rate += s.amplitude * w * np.cos(w * t + s.phase)
        return value, rate


@dataclass(frozen=True, slots=True)
class AngularMotion:
    """Attitude history C_b^n(t) of a base, fixed in position unless ``drive_from_s`` is set.

    drive_from_s, drive_accel_n : from that time on the base accelerates at ``drive_accel_n``
    (ENU, m/s²): a "static" base that is driven away (disturbance tests). The simulator adds the
    acceleration to the specific force; the small Coriolis and transport terms of the resulting
    velocity are left out (the test is of detection, not of navigation).
    """

    heading: AngleProfile = field(default_factory=AngleProfile)
    pitch: AngleProfile = field(default_factory=AngleProfile)
    roll: AngleProfile = field(default_factory=AngleProfile)
    drive_from_s: float | None = None
    drive_accel_n: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def body_rate_and_force(self, site: Site, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """C_b^n (…, 3, 3), ω_ib^b (…, 3) rad/s and f^b (…, 3) m/s² at times t on a base at ``site``.

        ω_ib^b = ω_nb^b + C_n^b ω_ie^n and f^b = C_n^b ([0, 0, g] + drive acceleration).
        """
        C_b_n, omega_nb_b = self.attitude_and_rate(t)
        C_n_b = np.swapaxes(C_b_n, -1, -2)
        omega_ib_b = omega_nb_b + C_n_b @ site.omega_ie_n
        f_b = (C_n_b @ (self.accel_n(t) + np.array([0.0, 0.0, site.gravity]))[..., None])[..., 0]
        return C_b_n, omega_ib_b, f_b

    def accel_n(self, t: np.ndarray) -> np.ndarray:
        """Linear acceleration of the base (..., 3), m/s² ENU."""
        t = np.asarray(t, dtype=float)
        on = np.zeros_like(t) if self.drive_from_s is None else (t >= self.drive_from_s).astype(float)
        return on[..., None] * np.asarray(self.drive_accel_n)

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """C_b^n at times t, shape (..., 3, 3)."""
        return dcm_from_euler(self.heading.value_and_rate(t)[0], self.pitch.value_and_rate(t)[0],
                              self.roll.value_and_rate(t)[0])

    def attitude_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """C_b^n (..., 3, 3) and ω_nb^b (..., 3, rad/s) at times t.

        With C_b^n = Rz(-ψ) Rx(θ) Ry(γ):
        ω_nb^b = Ry(γ)ᵀ ([θ̇, 0, 0] + Rx(θ)ᵀ [0, 0, -ψ̇]) + [0, γ̇, 0].
        """
        psi, psi_dot = self.heading.value_and_rate(t)
        theta, theta_dot = self.pitch.value_and_rate(t)
        gamma, gamma_dot = self.roll.value_and_rate(t)
        yaw_dot = -psi_dot  # counter-clockwise yaw rate about Up
        sp, cp = np.sin(theta), np.cos(theta)
        sr, cr = np.sin(gamma), np.cos(gamma)
        v = np.stack((theta_dot, sp * yaw_dot, cp * yaw_dot), axis=-1)
        omega_nb_b = np.stack((cr * v[..., 0] - sr * v[..., 2],
                               v[..., 1] + gamma_dot,
                               sr * v[..., 0] + cr * v[..., 2]), axis=-1)
        return dcm_from_euler(psi, theta, gamma), omega_nb_b
