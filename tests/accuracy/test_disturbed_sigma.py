"""σ of the attitude a moving base carries on (service/align/disturbance.py, service/pipeline.py).

When a base meant to stay in place moves, the records are ``disturbed``: the estimate of the detection window's start,
carried on by the gyros. GIVEN a swinging base driven off 1 s into its alignment, THEN that estimate had 1 s of data
and its σ says so: the heading is unknown (σ 103.9°, the cap of an unknown angle). The σ of the estimate at the
detection, 2 s later, is 3.8°, and the carried heading is up to 180° off. GIVEN gyros whose output is 57×
too large (°/s read as rad/s) on a static base, THEN the same holds: the misread rotation looks like motion at once,
and every disturbed record's σ covers its error (149° off under 3.8° without it). The bias the data then show, far
beyond the Earth's rate, points the operator at the gyros' units and the time base.
"""
from __future__ import annotations

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, dcm_from_quat, misalignment
from sinsalign.service.align.sensor_model import SIGMA_UNKNOWN_DEG, AttitudeSigma, SensorGrade, carried_sigma
from sinsalign.service.config import Config
from sinsalign.service.pipeline import build_pipeline
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.parked import Signal, SmoothStep
from sinsalign.tools.sim.scenarios import _swing_driven, get_scenario


def disturbed(scenario, seed: int, gyro_factor: float = 1.0):
    """(|heading error| deg, heading σ deg) of the ``disturbed`` records of ``scenario``, and its pipeline."""
    scenario = scenario.for_seed(seed)
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s, seed,
                        chunk_samples=10**7)
    pipeline = build_pipeline(Config(), scenario.site, scenario.rate_hz, scenario.stated_datasheet())
    records = [r for r in pipeline.process(chunk.t, gyro_factor * chunk.dtheta, chunk.dv) if r.phase == "disturbed"]
    truth = chunk.C_b_n_true[np.searchsorted(chunk.t, [r.t for r in records])]
    errors = np.array([abs(misalignment(dcm_from_quat(np.array(r.q)), C)[2]) / DEG
                       for r, C in zip(records, truth, strict=True)])
    return errors, np.array([r.heading_sigma_deg for r in records]), pipeline


@pytest.mark.parametrize("seed", [3, 4])
def test_a_base_driven_off_at_once_carries_an_unknown_heading(seed):
    scenario = _swing_driven("drive-off-at-1-s", "driven north from 1 s, 10 m/s at 11 s",
                             Signal(terms=(SmoothStep(1.0, 10.0, 10.0),)), 30.0, ((1.0, 2.0),))
    errors, sigma, _ = disturbed(scenario, seed)
    assert len(errors) >= 25
    assert np.all(sigma == pytest.approx(SIGMA_UNKNOWN_DEG))


def test_gyros_read_57_times_too_large_never_carry_a_heading_beyond_its_sigma():
    errors, sigma, pipeline = disturbed(get_scenario("seed001-static"), 5, gyro_factor=1.0 / DEG)
    assert len(errors) >= 100 and errors.max() > 90.0   # the misread rotation turned the carried heading
    assert np.all(errors <= 1.8 * sigma)   # 180° at most: an unknown angle's σ covers it
    assert "check the gyros' units and imu.rate_hz" in pipeline.last_notice   # the operator is pointed at the scale


def test_a_carried_attitude_drifts_with_the_gyros():
    """Its σ grows by the gyro bias times the time and the angle random walk, on every axis, up to the cap."""
    grade = SensorGrade(gyro_bias_rad_s=1e-5, gyro_arw_rad_rts=1e-4, acc_bias_ms2=0.0, acc_vrw_ms_rts=0.0)
    sigma = carried_sigma(AttitudeSigma(0.3, 0.01), grade, 100.0)
    drift2_deg2 = ((1e-5 * 100.0) ** 2 + 1e-8 * 100.0) / DEG**2
    assert sigma.heading_deg == pytest.approx(np.sqrt(0.3**2 + drift2_deg2))
    assert sigma.level_deg == pytest.approx(np.sqrt(0.01**2 + drift2_deg2))
    assert carried_sigma(AttitudeSigma(0.3, 0.01), grade, 0.0) == AttitudeSigma(0.3, 0.01)
    assert carried_sigma(AttitudeSigma(0.3, 0.01), grade, 1e9).heading_deg == SIGMA_UNKNOWN_DEG
