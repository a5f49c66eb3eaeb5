"""Scenarios with a tactical or MEMS IMU in place of the scenario's own, its datasheet stating the truth."""
from __future__ import annotations

from dataclasses import replace

from sinsalign.service.align.conventions import DH_TO_RS, DRH_TO_RRS, UG_TO_MS2
from sinsalign.tools.sim.imu import ImuErrors
from sinsalign.tools.sim.scenarios import Scenario, get_scenario, grade_of


def poor_imu(name: str, seed: int, gyro_bias_deg_h: float, gyro_arw_deg_rth: float, acc_bias_ug: float,
             acc_vrw_ug_rthz: float = 100.0) -> Scenario:
    """``name`` as ``seed`` runs it with gyro biases ±``gyro_bias_deg_h`` and accelerometer biases ±``acc_bias_ug``
    (the seed draws the signs, as :meth:`Scenario.for_seed` does), the given noise densities, and a datasheet that
    states them."""
    errors = ImuErrors(gyro_bias_rad_s=(gyro_bias_deg_h * DH_TO_RS,) * 3,
                       gyro_arw_rad_rts=gyro_arw_deg_rth * DRH_TO_RRS, acc_bias_ms2=(acc_bias_ug * UG_TO_MS2,) * 3,
                       acc_vrw_ms_rts=acc_vrw_ug_rthz * UG_TO_MS2)
    scenario = replace(get_scenario(name), errors=errors, errors_for_seed=None, random_bias_signs=True)
    return replace(scenario.for_seed(seed), grade=grade_of(errors, scenario.rate_hz))
