"""Simulated aiding sensors on a driving vehicle: odometer / DVL body velocity (seed 003).

The sensor sits at lever arm l^b from the IMU (body axes, m) and measures that point's velocity
over ground in body axes, V_P^b = V^b + ω_eb^b × l^b with ω_eb^b = ω_nb^b + C_n^b ω_en^n, times
(1 + scale factor) per axis, plus white noise; written as the pinned body-velocity log.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from sinsalign.protocol.aiding_log import KINDS
from sinsalign.protocol.imu_log import write_header, write_rows
from sinsalign.service.align.conventions import cross
from sinsalign.service.align.earth import transport_rate_n

from .scenarios import Scenario
from .vehicle import VehicleMotion


def body_velocity(motion: VehicleMotion, t: np.ndarray, lever_b: np.ndarray | None = None,
                  scale: np.ndarray | None = None, noise_std_mps: float = 0.0,
                  rng: np.random.Generator | None = None) -> np.ndarray:
    """Measured V_P^b (N, 3) in m/s at times t (N,); lever arm and scale factors default to zero."""
    lever_b = np.zeros(3) if lever_b is None else np.asarray(lever_b, dtype=float)
    scale = np.zeros(3) if scale is None else np.asarray(scale, dtype=float)
    C_b_n, omega_nb_b = motion.attitude_profiles.attitude_and_rate(t)
    _, V_b, V_n = motion.velocity_n(t)
    lat, _, h = np.moveaxis(motion.position(t), -1, 0)
    omega_en_n = transport_rate_n(V_n, lat, h)
    omega_eb_b = omega_nb_b + (np.swapaxes(C_b_n, -1, -2) @ omega_en_n[..., None])[..., 0]
    measured = (V_b + cross(omega_eb_b, np.broadcast_to(lever_b, V_b.shape))) * (1.0 + scale)
    if noise_std_mps:
        measured = measured + noise_std_mps * (rng or np.random.default_rng()).standard_normal(measured.shape)
    return measured


def write_body_velocity_log(path: str | Path, t: np.ndarray, v_b: np.ndarray, vel_std_mps: float | None = None) -> Path:
    """The pinned body-velocity log: ``t,vx,vy,vz`` with an optional ``# vel_std_mps=`` key."""
    path = Path(path)
    with open(path, "w", encoding="utf-8") as f:
        write_header(f, {} if vel_std_mps is None else {"vel_std_mps": vel_std_mps}, KINDS["odo"].columns)
        write_rows(f, np.column_stack((t, v_b)))
    return path


def odometer_epochs(scenario: Scenario, seed: int) -> np.ndarray:
    """The scenario's odometer readings (N, 4): t, V_P^b (seeded; a noise stream apart from the IMU's)."""
    odo = scenario.odometer
    t = np.arange(1, round(scenario.duration_s * odo.rate_hz) + 1) / odo.rate_hz
    v = body_velocity(scenario.motion, t, np.asarray(odo.lever_b), np.full(3, odo.scale), odo.noise_mps,
                      np.random.default_rng([seed, 3]))
    return np.column_stack((t, v))


def with_odometer_faults(epochs: np.ndarray, dropout_s: tuple[float, float] | None = None,
                         slip: tuple[float, float, float] | None = None, swapped: int = 0,
                         seed: int = 0) -> np.ndarray:
    """Odometer epochs (N, 4) with faults: no epochs inside ``dropout_s`` (start, end); a wheel slip
    ``(start_s, length_s, extra_mps)`` reading the forward axis fast; ``swapped`` pairs of
    neighbouring epochs sent out of order."""
    out = epochs.copy()
    if slip is not None:
        start, length, extra = slip
        out[(out[:, 0] >= start) & (out[:, 0] < start + length), 2] += extra
    if dropout_s is not None:
        out = out[(out[:, 0] < dropout_s[0]) | (out[:, 0] >= dropout_s[1])]
    if swapped:
        for k in np.random.default_rng([seed, 4]).choice(len(out) - 1, swapped, replace=False):
            out[[k, k + 1]] = out[[k + 1, k]]
    return out
