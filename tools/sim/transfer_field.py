"""A poor slave against a real master: the per-seed draws of the ``transfer-mems`` scenario.

A MEMS IMU in a pod, a camera head or a weapon, bolted to a road vehicle whose navigation-grade INS is the master.
Frames as motion.py (n = ENU, body = Right-Front-Up; the slave's mounting C_bs^bm from (heading, pitch, roll)).
The vehicle drives straight north in traffic, its speed swinging between 12 and 16 m/s (about ±1 m/s²: the
mount's yaw is barely observable from that alone), is rolled ±30° between 30 and 75 s, then drives on level to
100 s. The slave sits at a lever arm from the master's point that its configuration does not know.
"""
from __future__ import annotations

import numpy as np
from sinsalign.service.align.conventions import DEG, DH_TO_RS, DRH_TO_RRS, UG_TO_MS2, dcm_from_euler
from sinsalign.service.align.earth import Site

from .imu import ImuErrors
from .motion import AngleProfile, AngularMotion, Sinusoid
from .vehicle import MountedMotion, VehicleMotion

TRANSFER_SITE = Site(31.0 * DEG, 121.0 * DEG, 10.0)
DURATION_S = 100.0
ROLLS_S = (30.0, 75.0)
"""The rolls start at 30 s and end at 75 s."""
ROLL_DEG = 30.0
MOUNT_DEG = (12.0, -4.0, 7.0)
"""The slave's mounting off the master (heading, pitch, roll, deg)."""
LEVER_M = (0.4, 1.2, -0.3)
"""From the master's point to the slave, master body axes (m): unknown to the slave's configuration."""
MEMS_STREAM = 12
"""Seed stream of the slave's error magnitudes and the roll rate (signs: scenarios.py's stream 5)."""
GYRO_BIAS_DEG_H = (100.0, 300.0)
GYRO_ARW_DEG_RTH = (0.1, 0.5)
ACC_BIAS_MG = (1.0, 10.0)
ACC_VRW_UG_RTHZ = 50.0
ROLL_RATE_DEG_S = (5.0, 10.0)
SPEED_MPS = (14.0, 2.0)
"""Mean speed and the amplitude of its swing (m/s)."""
SPEED_PERIOD_S = (8.0, 15.0)


def poor_slave_errors(seed: int) -> ImuErrors:
    """The MEMS slave of one seed: per axis a gyro bias of 100–300°/h and an accelerometer bias of 1–10 mg
    (positive here; the scenario draws the signs), one angle random walk of 0.1–0.5°/√h, 50 µg/√Hz."""
    rng = np.random.default_rng([seed, MEMS_STREAM])
    gyro = rng.uniform(*GYRO_BIAS_DEG_H, size=3) * DH_TO_RS
    acc = rng.uniform(*ACC_BIAS_MG, size=3) * 1000.0 * UG_TO_MS2
    return ImuErrors(gyro_bias_rad_s=tuple(float(v) for v in gyro), acc_bias_ms2=tuple(float(v) for v in acc),
                     gyro_arw_rad_rts=float(rng.uniform(*GYRO_ARW_DEG_RTH)) * DRH_TO_RRS,
                     acc_vrw_ms_rts=ACC_VRW_UG_RTHZ * UG_TO_MS2)


def roll_profile(rate_deg_s: float) -> AngleProfile:
    """±30° rolls at an average ``rate_deg_s`` from 30 s, back level at 75 s: 0 → +30° at half the rate, then
    swings of 60° (raised-cosine, the peak rate π/2 times the average), the last one back to 0."""
    transition_s = 2.0 * ROLL_DEG / rate_deg_s
    start_s, end_s = ROLLS_S
    steps, t, sign = [], start_s, 1.0
    while t + 2.0 * transition_s <= end_s:
        steps.append((t, sign * ROLL_DEG * DEG))
        t, sign = t + transition_s, -sign
    steps.append((end_s - transition_s, 0.0))
    return AngleProfile(0.0, steps=tuple(steps), transition_s=transition_s)


def poor_slave_motion(seed: int) -> MountedMotion:
    """One seed's drive: north at 14 ± 2 m/s (a sinusoid of 8–15 s period and random phase), rolls at 5–10°/s over
    30–75 s (period, phase and roll rate drawn per seed)."""
    rng = np.random.default_rng([seed, MEMS_STREAM + 1])
    rate = float(rng.uniform(*ROLL_RATE_DEG_S))
    swing = Sinusoid(SPEED_MPS[1], 1.0 / float(rng.uniform(*SPEED_PERIOD_S)), float(rng.uniform(0.0, 2.0 * np.pi)))
    vehicle = VehicleMotion(TRANSFER_SITE, DURATION_S, AngularMotion(roll=roll_profile(rate)),
                            AngleProfile(SPEED_MPS[0], sinusoids=(swing,)))
    M = dcm_from_euler(*(np.array(MOUNT_DEG) * DEG))
    return MountedMotion(vehicle, tuple(tuple(float(v) for v in row) for row in M), LEVER_M)
