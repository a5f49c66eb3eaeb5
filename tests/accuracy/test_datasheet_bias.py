"""A datasheet that understates the gyro bias (service/align/noise_check.py, the residual's trend).

GIVEN a fixed base (static or swinging, seed 001) whose gyros have 0.1°/h or 1°/h of bias on every axis while the
log's datasheet states 0.02°/h, THEN the residual's t² trend shows the bias, the operator is told, and σ takes it:
no record is converged while more than 3σ off, and σ stays within 10× the error at the end (honest, not useless).
Without the check the static base would be reported `aligned`, converged, 1.97° off under a σ of 0.09°. GIVEN gyros
at the datasheet's bias, THEN nothing is told and σ keeps the datasheet's bias.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from sinsalign.service.align.conventions import DEG, DH_TO_RS, dcm_from_quat, misalignment
from sinsalign.service.config import Config
from sinsalign.service.pipeline import build_pipeline
from sinsalign.tools.sim.imu import simulate
from sinsalign.tools.sim.scenarios import get_scenario


def aligned(name: str, bias_deg_h: float, seed: int, signs: tuple[float, float, float] = (1.0, -1.0, 1.0)):
    """(records, heading errors (deg), pipeline) of ``name`` with gyro biases ``signs`` × b°/h (body axes)."""
    scenario = get_scenario(name).for_seed(seed)
    bias = tuple(float(v) * bias_deg_h * DH_TO_RS for v in signs)
    scenario = replace(scenario, errors=replace(scenario.errors, gyro_bias_rad_s=bias))
    (chunk,) = simulate(scenario.motion, scenario.site, scenario.errors, scenario.rate_hz, scenario.duration_s, seed,
                        chunk_samples=10**7)
    pipeline = build_pipeline(Config(), scenario.site, scenario.rate_hz, scenario.stated_datasheet())
    records = pipeline.process(chunk.t, chunk.dtheta, chunk.dv)
    truth = chunk.C_b_n_true[np.searchsorted(chunk.t, [r.t for r in records])]
    errors = np.array([abs(misalignment(dcm_from_quat(np.array(r.q)), C)[2]) / DEG
                       for r, C in zip(records, truth, strict=True)])
    return records, errors, pipeline


@pytest.mark.parametrize(("name", "bias_deg_h", "seed"), [("seed001-static", 1.0, 0), ("seed001-static", 0.1, 1),
                                                          ("seed001-swing", 1.0, 2), ("seed001-swing", 0.1, 3)])
def test_a_gyro_bias_beyond_the_datasheet_s_is_told_and_sigma_takes_it(name, bias_deg_h, seed):
    records, errors, pipeline = aligned(name, bias_deg_h, seed)
    sigma = np.array([r.heading_sigma_deg for r in records])
    converged = np.array([r.converged for r in records])
    assert "gyro_bias_deg_h" in pipeline.last_notice and "units" not in pipeline.last_notice   # below Earth's rate
    assert not (converged & (errors > 3.0 * sigma)).any()
    assert errors[-1] <= 3.0 * sigma[-1] <= 30.0 * max(errors[-1], 0.1 * bias_deg_h)


@pytest.mark.parametrize(("signs", "seed"), [((1.0, 1.0, 1.0), 6), ((1.0, -1.0, 1.0), 7), ((-1.0, 1.0, 1.0), 8)])
def test_an_imu_turned_through_four_headings_shows_every_horizontal_bias(signs, seed):
    """On a fixed base the check sees the north component only: with biases (+b, +b, +b) at seed 001's heading the
    east one is 4× the north, and 6× the datasheet's per axis goes unseen (docs/field-data.md). A turntable's four
    positions turn each horizontal axis north in turn: 10× the datasheet's is told whatever the signs, and no record is
    converged beyond 3σ."""
    stated = get_scenario("turntable-positions").grade.gyro_bias_rad_s / DH_TO_RS
    records, errors, pipeline = aligned("turntable-positions", 10.0 * stated, seed, signs)
    sigma = np.array([r.heading_sigma_deg for r in records])
    converged = np.array([r.converged for r in records])
    # a bias turning with the table can also read as the gyro's walk: either way σ takes a gyro figure the data show
    assert "gyro_bias_deg_h" in pipeline.last_notice or "gyro_arw_deg_rth" in pipeline.last_notice
    assert not (converged & (errors > 3.0 * sigma)).any()
    assert errors[-1] <= 3.0 * sigma[-1]


@pytest.mark.parametrize(("name", "seed"), [("seed001-static", 4), ("seed001-swing", 5)])
def test_gyros_at_the_datasheet_s_bias_change_nothing(name, seed):
    stated = get_scenario(name).grade.gyro_bias_rad_s
    records, errors, pipeline = aligned(name, stated / DH_TO_RS, seed)
    assert pipeline.last_notice is None and pipeline.sigma_grade.gyro_bias_rad_s == stated
    assert records[-1].converged and errors[-1] <= 3.0 * records[-1].heading_sigma_deg
