"""Scenarios with a tactical or MEMS IMU in place of the scenario's own, its datasheet stating the truth."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from sinsalign.service.align.conventions import DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from sinsalign.tools.sim.imu import ImuErrors
from sinsalign.tools.sim.scenarios import Scenario, get_scenario, grade_of


def poor_imu(name: str, seed: int, gyro_bias_deg_h: float, gyro_arw_deg_rth: float, acc_bias_ug: float,
             acc_vrw_ug_rthz: float = 100.0) -> Scenario:
    """``name`` as ``seed`` runs it with gyro biases ±``gyro_bias_deg_h`` and accelerometer biases ±``acc_bias_ug``
    (signs drawn from the seed), the given noise densities, and a datasheet that states them."""
    gyro_signs, acc_signs = np.random.default_rng(seed).choice([-1.0, 1.0], (2, 3))
    errors = ImuErrors(gyro_bias_rad_s=tuple(gyro_bias_deg_h * DH_TO_RS * gyro_signs),
                       gyro_arw_rad_rts=gyro_arw_deg_rth * DRH_TO_RRS,
                       acc_bias_ms2=tuple(acc_bias_ug * UG_TO_MS2 * acc_signs),
                       acc_vrw_ms_rts=acc_vrw_ug_rthz * UG_TO_MS2)
    scenario = get_scenario(name).for_seed(seed)
    return replace(scenario, errors=errors, grade=grade_of(errors, scenario.rate_hz))
